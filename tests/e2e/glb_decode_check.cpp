// Decodes a compressed export (fourd-export --compress: EXT_meshopt_compression with
// meshoptimizer's decoder, KHR_mesh_quantization's integer attributes, the mesh node's
// dequantising transform) and compares every frame with the plain export of the same asset:
// every morph target's vertices (template + displacement, in the mesh's scene frame), normals,
// the clips' names, key times, weights and root keys. Prints the errors; exits 1 when a vertex
// is further than MAX_MM from the plain export's or anything else differs.
// usage: glb_decode_check ASSET PLAIN.glb COMPRESSED.glb MAX_MM
#include <meshoptimizer.h>

#include <Eigen/Geometry>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <fmt/format.h>
#include <map>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "pipeline/core/error.h"
#include "pipeline/core/files.h"
#include "runtime/asset.h"
#include "runtime/gltf_export.h"

namespace {

using fourd::InputError;
using nlohmann::json;

// A .glb's JSON and its buffers, compressed views decoded.
struct Glb {
  json doc;
  std::vector<std::vector<unsigned char>> buffers;
  std::vector<std::vector<unsigned char>> views;  // every view's bytes, decoded
};

Glb read_glb(const std::string& file) {
  const std::string bytes = fourd::read_file(file);
  auto u32 = [&](std::size_t at) {
    std::uint32_t v;
    std::memcpy(&v, bytes.data() + at, 4);
    return v;
  };
  if (bytes.size() < 20 || bytes.compare(0, 4, "glTF") != 0)
    throw InputError(file + ": not a .glb");
  Glb glb;
  const std::uint32_t json_length = u32(12);
  glb.doc = json::parse(bytes.substr(20, json_length));
  glb.buffers.resize(glb.doc["buffers"].size());
  const std::size_t bin = 20 + json_length;
  if (bin + 8 <= bytes.size()) {
    const std::uint32_t length = u32(bin);
    glb.buffers[0].assign(bytes.begin() + bin + 8, bytes.begin() + bin + 8 + length);
  }
  for (const json& view : glb.doc["bufferViews"]) {
    std::vector<unsigned char> out(view.at("byteLength").get<std::size_t>());
    if (view.contains("extensions") && view["extensions"].contains("EXT_meshopt_compression")) {
      const json& ext = view["extensions"]["EXT_meshopt_compression"];
      const std::vector<unsigned char>& source = glb.buffers.at(ext.at("buffer").get<int>());
      const unsigned char* data = source.data() + ext.value("byteOffset", 0);
      const std::size_t length = ext.at("byteLength"), count = ext.at("count"),
                        stride = ext.at("byteStride");
      const std::string mode = ext.at("mode");
      const int rc = mode == "ATTRIBUTES"
                         ? meshopt_decodeVertexBuffer(out.data(), count, stride, data, length)
                         : meshopt_decodeIndexBuffer(out.data(), count, stride, data, length);
      if (rc != 0 || ext.value("filter", "NONE") != "NONE")
        throw InputError(fmt::format("{}: cannot decode a {} view (code {})", file, mode, rc));
    } else {
      const std::vector<unsigned char>& source = glb.buffers.at(view.at("buffer").get<int>());
      const std::size_t offset = view.value("byteOffset", 0);
      std::memcpy(out.data(), source.data() + offset, out.size());
    }
    glb.views.push_back(std::move(out));
  }
  return glb;
}

// An accessor's elements as floats (normalised integers mapped to [-1, 1] / [0, 1]).
std::vector<std::vector<double>> accessor(const Glb& glb, int index) {
  const json& a = glb.doc["accessors"].at(index);
  const json& view = glb.doc["bufferViews"].at(a.at("bufferView").get<int>());
  const std::vector<unsigned char>& bytes = glb.views.at(a.at("bufferView").get<int>());
  const std::map<std::string, int> sizes{{"SCALAR", 1}, {"VEC2", 2}, {"VEC3", 3}, {"VEC4", 4}};
  const int components = sizes.at(a.at("type"));
  const int type = a.at("componentType");
  const bool normalized = a.value("normalized", false);
  const int size = type == 5126 || type == 5125 ? 4 : (type == 5122 || type == 5123 ? 2 : 1);
  const std::size_t stride = view.value("byteStride", components * size);
  const std::size_t offset = a.value("byteOffset", 0);
  std::vector<std::vector<double>> out(a.at("count").get<std::size_t>(),
                                       std::vector<double>(components));
  for (std::size_t e = 0; e < out.size(); ++e) {
    for (int c = 0; c < components; ++c) {
      const unsigned char* p = bytes.data() + offset + e * stride + c * size;
      double v = 0;
      switch (type) {
        case 5126: { float f; std::memcpy(&f, p, 4); v = f; break; }
        case 5125: { std::uint32_t i; std::memcpy(&i, p, 4); v = i; break; }
        case 5122: { std::int16_t i; std::memcpy(&i, p, 2); v = normalized ? std::max(i / 32767.0, -1.0) : i; break; }
        case 5123: { std::uint16_t i; std::memcpy(&i, p, 2); v = normalized ? i / 65535.0 : i; break; }
        case 5120: { std::int8_t i; std::memcpy(&i, p, 1); v = normalized ? std::max(i / 127.0, -1.0) : i; break; }
        case 5121: { std::uint8_t i; std::memcpy(&i, p, 1); v = normalized ? i / 255.0 : i; break; }
        default: throw InputError(fmt::format("accessor {}: component type {}", index, type));
      }
      out[e][c] = v;
    }
  }
  return out;
}

// The local transform of the node that holds the mesh (static TRS).
Eigen::Affine3d mesh_node_transform(const Glb& glb, int* node_index) {
  const json& nodes = glb.doc["nodes"];
  for (std::size_t i = 0; i < nodes.size(); ++i) {
    if (!nodes[i].contains("mesh")) continue;
    *node_index = static_cast<int>(i);
    Eigen::Affine3d m = Eigen::Affine3d::Identity();
    const json& n = nodes[i];
    if (n.contains("translation"))
      m.translate(Eigen::Vector3d(n["translation"][0], n["translation"][1], n["translation"][2]));
    if (n.contains("rotation"))
      m.rotate(Eigen::Quaterniond(n["rotation"][3], n["rotation"][0], n["rotation"][1], n["rotation"][2]));
    if (n.contains("scale"))
      m.scale(Eigen::Vector3d(n["scale"][0], n["scale"][1], n["scale"][2]));
    return m;
  }
  throw InputError("no node holds a mesh");
}

// Every morph target's vertices (template + displacement) and normals, in the mesh node's
// parent frame, the vertices in the order of `order` (per vertex: its (source, uv) key).
struct Frames {
  std::vector<std::vector<Eigen::Vector3d>> positions, normals;
};

Frames evaluate(const Glb& glb) {
  int node = 0;
  const Eigen::Affine3d m = mesh_node_transform(glb, &node);
  const json& primitive = glb.doc["meshes"][0]["primitives"][0];
  const auto base_p = accessor(glb, primitive["attributes"]["POSITION"]);
  const auto base_n = accessor(glb, primitive["attributes"]["NORMAL"]);
  Frames out;
  for (const json& target : primitive["targets"]) {
    const auto dp = accessor(glb, target["POSITION"]);
    const auto dn = accessor(glb, target["NORMAL"]);
    std::vector<Eigen::Vector3d> p(dp.size()), n(dp.size());
    for (std::size_t v = 0; v < dp.size(); ++v) {
      p[v] = m * Eigen::Vector3d(base_p[v][0] + dp[v][0], base_p[v][1] + dp[v][1],
                                 base_p[v][2] + dp[v][2]);
      n[v] = (m.linear() * Eigen::Vector3d(base_n[v][0] + dn[v][0], base_n[v][1] + dn[v][1],
                                           base_n[v][2] + dn[v][2]))
                 .normalized();
    }
    out.positions.push_back(std::move(p));
    out.normals.push_back(std::move(n));
  }
  return out;
}

}  // namespace

int main(int argc, char** argv) {
  using namespace fourd;
  if (argc != 5) {
    fmt::print(stderr, "usage: glb_decode_check ASSET PLAIN.glb COMPRESSED.glb MAX_MM\n");
    return kExitUsage;
  }
  try {
    const double max_mm = std::stod(argv[4]);
    const Asset asset = load_asset(argv[1]);
    const Mesh base = asset_template(asset);
    const gltf::ExportVertices plain_order = glb_vertices(base, GlbOptions{});
    GlbOptions compressed_options;
    compressed_options.compress = true;
    const gltf::ExportVertices packed_order = glb_vertices(base, compressed_options);
    const Glb plain = read_glb(argv[2]);
    const Glb packed = read_glb(argv[3]);
    // Compressed vertex -> plain vertex, through the template vertex and UV each copies.
    std::map<std::pair<int, int>, int> plain_index;
    for (std::size_t i = 0; i < plain_order.source.size(); ++i)
      plain_index[{plain_order.source[i], plain_order.uv[i]}] = static_cast<int>(i);
    std::vector<int> to_plain;
    for (std::size_t i = 0; i < packed_order.source.size(); ++i)
      to_plain.push_back(plain_index.at({packed_order.source[i], packed_order.uv[i]}));

    std::vector<std::string> failures;
    const Frames a = evaluate(plain), b = evaluate(packed);
    if (a.positions.size() != b.positions.size() ||
        b.positions.front().size() != to_plain.size())
      failures.push_back(fmt::format("{} / {} morph targets, {} vertices ({} expected)",
                                     a.positions.size(), b.positions.size(),
                                     b.positions.front().size(), to_plain.size()));
    double max_error = 0, sum = 0, max_angle = 0, sum_angle = 0;
    std::size_t count = 0, worst_target = 0;
    for (std::size_t t = 0; failures.empty() && t < a.positions.size(); ++t) {
      for (std::size_t v = 0; v < to_plain.size(); ++v) {
        const double e = 1e3 * (b.positions[t][v] - a.positions[t][to_plain[v]]).norm();
        const double angle = std::acos(std::clamp(b.normals[t][v].dot(a.normals[t][to_plain[v]]),
                                                  -1.0, 1.0)) * 180 / M_PI;
        if (e > max_error) worst_target = t;
        max_error = std::max(max_error, e);
        max_angle = std::max(max_angle, angle);
        sum += e;
        sum_angle += angle;
        ++count;
      }
    }
    fmt::print("vertices after decode vs the plain export ({} frames x {} vertices): max {:.3f} "
               "mm (frame {}), mean {:.3f} mm; normals: max {:.1f} deg, mean {:.2f} deg\n",
               a.positions.size(), to_plain.size(), max_error, worst_target,
               count ? sum / count : 0.0, max_angle, count ? sum_angle / count : 0.0);
    if (max_error > max_mm)
      failures.push_back(fmt::format("max vertex error {:.3f} mm > {} mm", max_error, max_mm));
    // Clips: names, key times, weights and root keys, sampler by sampler.
    const json& anims_a = plain.doc["animations"];
    const json& anims_b = packed.doc["animations"];
    double key_error = 0;
    if (anims_a.size() != anims_b.size()) {
      failures.push_back(fmt::format("{} clips, the plain export has {}", anims_b.size(), anims_a.size()));
    } else {
      for (std::size_t i = 0; i < anims_a.size(); ++i) {
        if (anims_a[i]["name"] != anims_b[i]["name"])
          failures.push_back(fmt::format("clip {} is '{}', not '{}'", i,
                                         anims_b[i]["name"].get<std::string>(),
                                         anims_a[i]["name"].get<std::string>()));
        for (std::size_t s = 0; s < anims_a[i]["samplers"].size(); ++s) {
          for (const char* key : {"input", "output"}) {
            const auto x = accessor(plain, anims_a[i]["samplers"][s][key]);
            const auto y = accessor(packed, anims_b[i]["samplers"][s][key]);
            if (x.size() != y.size()) {
              failures.push_back(fmt::format("clip {} sampler {}: {} keys, not {}", i, s, y.size(), x.size()));
              continue;
            }
            for (std::size_t k = 0; k < x.size(); ++k)
              for (std::size_t c = 0; c < x[k].size(); ++c)
                key_error = std::max(key_error, std::abs(x[k][c] - y[k][c]));
          }
        }
      }
    }
    fmt::print("clips: {}, largest key difference {:.3g}\n", anims_b.size(), key_error);
    if (key_error > 0) failures.push_back(fmt::format("animation keys differ by {:.3g}", key_error));
    for (const std::string& f : failures) fmt::print(stderr, "{}: {}\n", argv[3], f);
    return failures.empty() ? kExitOk : kExitFailure;
  } catch (const std::exception& e) {
    fmt::print(stderr, "glb_decode_check: {}\n", e.what());
    return kExitFailure;
  }
}
