#include "pipeline/geometry/components.h"

#include "pipeline/geometry/measures.h"
#include "pipeline/geometry/union_find.h"

namespace fourd {

std::vector<int> vertex_components(const Mesh& mesh, int* count) {
  UnionFind sets(mesh.num_vertices());
  for (const Tri& t : mesh.triangles) {
    sets.unite(t[0], t[1]);
    sets.unite(t[1], t[2]);
  }
  std::vector<int> of_root(mesh.num_vertices(), -1);
  int n = 0;
  for (const Tri& t : mesh.triangles) {
    int& c = of_root[sets.find(t[0])];
    if (c < 0) c = n++;
  }
  std::vector<int> component(mesh.num_vertices(), -1);
  for (const Tri& t : mesh.triangles) {
    for (int k = 0; k < 3; ++k) component[t[k]] = of_root[sets.find(t[k])];
  }
  if (count) *count = n;
  return component;
}

int count_components(const Mesh& mesh) {
  int count = 0;
  vertex_components(mesh, &count);
  return count;
}

Mesh largest_component(const Mesh& mesh) {
  int count = 0;
  const std::vector<int> component = vertex_components(mesh, &count);
  if (count == 0) return {};
  std::vector<double> area(count, 0.0);
  for (const Tri& t : mesh.triangles) area[component[t[0]]] += triangle_area(mesh, t);
  int best = 0;
  for (int c = 1; c < count; ++c) {
    if (area[c] > area[best]) best = c;
  }
  Mesh out;
  std::vector<int> index(mesh.num_vertices(), -1);
  for (const Tri& t : mesh.triangles) {
    if (component[t[0]] != best) continue;
    Tri nt;
    for (int k = 0; k < 3; ++k) {
      int& i = index[t[k]];
      if (i < 0) {
        i = static_cast<int>(out.positions.size());
        out.positions.push_back(mesh.positions[t[k]]);
      }
      nt[k] = i;
    }
    out.triangles.push_back(nt);
  }
  return out;
}

}  // namespace fourd
