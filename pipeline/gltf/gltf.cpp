// The one translation unit that compiles tinygltf (see gltf.h for how images are handled).
#define TINYGLTF_IMPLEMENTATION
#include "pipeline/gltf/gltf.h"

#include <fmt/format.h>

#include <meshoptimizer.h>

#include <cstring>
#include <map>
#include <nlohmann/json.hpp>
#include <numeric>
#include <opencv2/imgcodecs.hpp>
#include <sstream>

#include "pipeline/core/error.h"
#include "pipeline/core/files.h"

namespace fourd::gltf {
namespace {

Eigen::Matrix4d homogeneous(const Eigen::Matrix3d& linear) {
  Eigen::Matrix4d m = Eigen::Matrix4d::Identity();
  m.topLeftCorner<3, 3>() = linear;
  return m;
}

// Decodes embedded and external images with OpenCV. The pixels are stored as 8-bit BGR
// (component 3).
bool decode_image(tinygltf::Image* image, const int index, std::string* err, std::string*, int, int,
                  const unsigned char* bytes, int size, void* user_data) {
  // tinygltf hands over an image's buffer view without checking that the view lies inside its
  // buffer (user_data is the model being loaded, whose buffers are already read): check it.
  const auto* model = static_cast<const tinygltf::Model*>(user_data);
  if (model != nullptr && image->bufferView >= 0) {
    const tinygltf::BufferView& view = model->bufferViews.at(std::size_t(image->bufferView));
    const std::size_t buffer_size = model->buffers.at(std::size_t(view.buffer)).data.size();
    if (view.byteOffset > buffer_size || view.byteLength > buffer_size - view.byteOffset) {
      if (err)
        *err += fmt::format("image {}: buffer view {} (offset {}, {} bytes) runs past the end "
                            "of its buffer ({} bytes)\n",
                            index, image->bufferView, view.byteOffset, view.byteLength,
                            buffer_size);
      return false;
    }
  }
  if (size <= 0) {
    if (err) *err += fmt::format("image {}: no bytes\n", index);
    return false;
  }
  const cv::Mat encoded(1, size, CV_8UC1, const_cast<unsigned char*>(bytes));
  cv::Mat bgr = cv::imdecode(encoded, cv::IMREAD_COLOR);
  if (bgr.empty()) {
    if (err)
      *err += fmt::format("cannot decode image {} ('{}', {})\n", index, image->name,
                          image->mimeType.empty() ? image->uri : image->mimeType);
    return false;
  }
  if (!bgr.isContinuous()) bgr = bgr.clone();
  image->width = bgr.cols;
  image->height = bgr.rows;
  image->component = 3;
  image->bits = 8;
  image->pixel_type = TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE;
  image->image.assign(bgr.data, bgr.data + bgr.total() * bgr.elemSize());
  return true;
}

}  // namespace

Eigen::Matrix4d to_gltf_axes(const Eigen::Matrix4d& ours) {
  return homogeneous(kOurFromGltf.transpose()) * ours * homogeneous(kOurFromGltf);
}

Eigen::Quaterniond to_gltf_axes(const Eigen::Quaterniond& ours) {
  const Eigen::Quaterniond our_from_gltf(kOurFromGltf);
  return our_from_gltf.conjugate() * ours * our_from_gltf;
}

int BufferWriter::add_view(const void* bytes, std::size_t size, int target) {
  std::vector<unsigned char>& data = model_.buffers[0].data;
  data.resize((data.size() + 3) / 4 * 4, 0);  // accessors must start 4-byte aligned
  tinygltf::BufferView view;
  view.buffer = 0;
  view.byteOffset = data.size();
  view.byteLength = size;
  view.target = target;
  const auto* begin = static_cast<const unsigned char*>(bytes);
  data.insert(data.end(), begin, begin + size);
  model_.bufferViews.push_back(view);
  return static_cast<int>(model_.bufferViews.size()) - 1;
}

int BufferWriter::add_meshopt_view(const void* bytes, std::size_t count, std::size_t stride,
                                   MeshoptMode mode, int target) {
  std::vector<unsigned char> encoded;
  if (mode == MeshoptMode::kAttributes) {
    if (stride == 0 || stride % 4 != 0 || stride > 256)
      throw Error(fmt::format("meshopt attribute stride {} (a multiple of 4 up to 256)", stride));
    encoded.resize(meshopt_encodeVertexBufferBound(count, stride));
    encoded.resize(meshopt_encodeVertexBuffer(encoded.data(), encoded.size(), bytes, count, stride));
  } else {
    if ((stride != 2 && stride != 4) || count % 3 != 0)
      throw Error(fmt::format("meshopt triangles: stride {}, {} indices", stride, count));
    std::vector<unsigned int> indices(count);
    std::size_t vertices = 0;
    for (std::size_t i = 0; i < count; ++i) {
      if (stride == 2) {
        std::uint16_t v;
        std::memcpy(&v, static_cast<const unsigned char*>(bytes) + 2 * i, 2);
        indices[i] = v;
      } else {
        std::memcpy(&indices[i], static_cast<const unsigned char*>(bytes) + 4 * i, 4);
      }
      vertices = std::max<std::size_t>(vertices, indices[i] + 1);
    }
    encoded.resize(meshopt_encodeIndexBufferBound(count, vertices));
    encoded.resize(meshopt_encodeIndexBuffer(encoded.data(), encoded.size(), indices.data(), count));
  }
  if (encoded.empty()) throw Error("meshoptimizer could not encode a buffer view");
  const int view = add_view(encoded.data(), encoded.size(), target);
  if (target == TINYGLTF_TARGET_ARRAY_BUFFER) model_.bufferViews[view].byteStride = stride;
  meshopt_.push_back({view, stride, count, mode});
  return view;
}

int BufferWriter::add_png_texture(std::span<const unsigned char> png, const std::string& name) {
  return add_image_texture(png, "image/png", name);
}

int BufferWriter::add_image_texture(std::span<const unsigned char> bytes,
                                    const std::string& mime_type, const std::string& name) {
  tinygltf::Image image;
  image.name = name;
  image.mimeType = mime_type;
  image.bufferView = add_view(bytes.data(), bytes.size(), 0);
  model_.images.push_back(image);
  tinygltf::Sampler sampler;
  sampler.magFilter = TINYGLTF_TEXTURE_FILTER_LINEAR;
  sampler.minFilter = TINYGLTF_TEXTURE_FILTER_LINEAR_MIPMAP_LINEAR;
  model_.samplers.push_back(sampler);
  tinygltf::Texture texture;
  texture.source = static_cast<int>(model_.images.size()) - 1;
  texture.sampler = static_cast<int>(model_.samplers.size()) - 1;
  model_.textures.push_back(texture);
  return static_cast<int>(model_.textures.size()) - 1;
}

void add_linear_channel(tinygltf::Animation* animation, BufferWriter& buffer, int input, int node,
                        const char* path, const std::vector<float>& values, int type,
                        bool meshopt) {
  tinygltf::AnimationSampler sampler;
  sampler.input = input;
  const std::size_t components = tinygltf::GetNumComponentsInType(type);
  sampler.output =
      meshopt ? buffer.add_meshopt_accessor(values, values.size() / components,
                                            components * sizeof(float),
                                            TINYGLTF_COMPONENT_TYPE_FLOAT, type, 0, false)
              : buffer.add_accessor(values, TINYGLTF_COMPONENT_TYPE_FLOAT, type, 0);
  sampler.interpolation = "LINEAR";
  animation->samplers.push_back(sampler);
  tinygltf::AnimationChannel channel;
  channel.sampler = static_cast<int>(animation->samplers.size()) - 1;
  channel.target_node = node;
  channel.target_path = path;
  animation->channels.push_back(channel);
}

std::vector<float> rotation_keys(std::span<const Eigen::Quaterniond> ours) {
  std::vector<float> keys;
  keys.reserve(4 * ours.size());
  Eigen::Quaterniond previous = Eigen::Quaterniond::Identity();
  for (std::size_t f = 0; f < ours.size(); ++f) {
    Eigen::Quaterniond q = to_gltf_axes(ours[f].normalized());
    if (f > 0 && q.dot(previous) < 0) q.coeffs() *= -1;
    previous = q;
    keys.insert(keys.end(), {static_cast<float>(q.x()), static_cast<float>(q.y()),
                             static_cast<float>(q.z()), static_cast<float>(q.w())});
  }
  return keys;
}

ExportVertices export_vertices(const Mesh& mesh) {
  ExportVertices out;
  const int n = static_cast<int>(mesh.num_vertices());
  if (mesh.uv_triangles.empty()) {
    out.source.resize(n);
    std::iota(out.source.begin(), out.source.end(), 0);
    out.uv = mesh.uvs.empty() ? std::vector<int>(n, -1) : out.source;
    out.triangles = mesh.triangles;
    return out;
  }
  std::map<std::pair<int, int>, int> index;  // (vertex, uv) -> exported vertex
  out.triangles.resize(mesh.num_triangles());
  for (std::size_t f = 0; f < mesh.num_triangles(); ++f) {
    for (int c = 0; c < 3; ++c) {
      const std::pair<int, int> key{mesh.triangles[f][c], mesh.uv_triangles[f][c]};
      auto [it, added] = index.emplace(key, static_cast<int>(out.source.size()));
      if (added) {
        out.source.push_back(key.first);
        out.uv.push_back(key.second);
      }
      out.triangles[f][c] = it->second;
    }
  }
  return out;
}

void order_for_compression(ExportVertices* vertices) {
  const std::size_t n = vertices->source.size();
  std::vector<unsigned int> indices;
  for (const Tri& t : vertices->triangles)
    for (int c = 0; c < 3; ++c) indices.push_back(static_cast<unsigned int>(t[c]));
  meshopt_optimizeVertexCache(indices.data(), indices.data(), indices.size(), n);
  std::vector<unsigned int> remap(n);  // old -> new
  std::size_t used = meshopt_optimizeVertexFetchRemap(remap.data(), indices.data(), indices.size(), n);
  for (unsigned int& r : remap)
    if (r == ~0u) r = static_cast<unsigned int>(used++);
  ExportVertices out;
  out.source.resize(n);
  out.uv.resize(n);
  for (std::size_t v = 0; v < n; ++v) {
    out.source[remap[v]] = vertices->source[v];
    out.uv[remap[v]] = vertices->uv[v];
  }
  out.triangles.resize(vertices->triangles.size());
  for (std::size_t f = 0; f < out.triangles.size(); ++f)
    for (int c = 0; c < 3; ++c) out.triangles[f][c] = static_cast<int>(remap[indices[3 * f + c]]);
  *vertices = std::move(out);
}

tinygltf::Primitive add_mesh_primitive(BufferWriter& buffer, const Mesh& mesh, bool with_uvs,
                                       ExportVertices* vertices) {
  *vertices = export_vertices(mesh);
  std::vector<float> positions, normals, uvs;
  for (std::size_t i = 0; i < vertices->source.size(); ++i) {
    const int v = vertices->source[i];
    const Eigen::Vector3f p = to_gltf(mesh.positions[v]);
    const Eigen::Vector3f n = to_gltf(mesh.normals[v]);
    positions.insert(positions.end(), {p.x(), p.y(), p.z()});
    normals.insert(normals.end(), {n.x(), n.y(), n.z()});
    if (with_uvs) {
      const Vec2f& uv = mesh.uvs[vertices->uv[i]];
      uvs.insert(uvs.end(), {uv.x(), 1.0f - uv.y()});
    }
  }
  std::vector<std::uint32_t> indices;
  for (const Tri& t : vertices->triangles)
    for (int c = 0; c < 3; ++c) indices.push_back(static_cast<std::uint32_t>(t[c]));

  constexpr int kArray = TINYGLTF_TARGET_ARRAY_BUFFER;
  constexpr int kFloat = TINYGLTF_COMPONENT_TYPE_FLOAT;
  tinygltf::Primitive primitive;
  primitive.mode = TINYGLTF_MODE_TRIANGLES;
  primitive.attributes["POSITION"] =
      buffer.add_accessor(positions, kFloat, TINYGLTF_TYPE_VEC3, kArray, true);
  primitive.attributes["NORMAL"] = buffer.add_accessor(normals, kFloat, TINYGLTF_TYPE_VEC3, kArray);
  if (with_uvs)
    primitive.attributes["TEXCOORD_0"] =
        buffer.add_accessor(uvs, kFloat, TINYGLTF_TYPE_VEC2, kArray);
  primitive.indices =
      buffer.add_accessor(indices, TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT, TINYGLTF_TYPE_SCALAR,
                          TINYGLTF_TARGET_ELEMENT_ARRAY_BUFFER);
  return primitive;
}

namespace {

std::uint32_t read_u32(const std::string& bytes, std::size_t at) {
  std::uint32_t v = 0;
  std::memcpy(&v, bytes.data() + at, 4);
  return v;
}

void append_u32(std::string* out, std::uint32_t v) {
  out->append(reinterpret_cast<const char*>(&v), 4);
}

// Rewrites the JSON chunk of the GLB `glb` (tinygltf's: JSON chunk then BIN chunk) so that the
// views in `meshopt` are EXT_meshopt_compression views: the extension points at the encoded
// bytes where tinygltf wrote them (buffer 0), the view itself at its decoded place in a fallback
// buffer (buffer 1, no data).
std::string add_meshopt_extension(const std::string& glb, std::span<const MeshoptView> meshopt) {
  if (glb.size() < 20 || glb.compare(0, 4, "glTF") != 0)
    throw Error("tinygltf wrote no GLB header");
  const std::uint32_t json_length = read_u32(glb, 12);
  nlohmann::json json = nlohmann::json::parse(glb.substr(20, json_length));
  const std::string bin = glb.substr(20 + json_length);  // the BIN chunk, header included
  nlohmann::json& views = json["bufferViews"];
  const int fallback = static_cast<int>(json["buffers"].size());
  std::size_t fallback_size = 0;
  for (const MeshoptView& m : meshopt) {
    nlohmann::json& view = views.at(m.view);
    nlohmann::json ext;
    ext["buffer"] = view.at("buffer");
    ext["byteOffset"] = view.value("byteOffset", 0);
    ext["byteLength"] = view.at("byteLength");
    ext["byteStride"] = m.stride;
    ext["count"] = m.count;
    ext["mode"] = m.mode == MeshoptMode::kAttributes ? "ATTRIBUTES" : "TRIANGLES";
    fallback_size = (fallback_size + 3) / 4 * 4;
    view["buffer"] = fallback;
    view["byteOffset"] = fallback_size;
    view["byteLength"] = m.stride * m.count;
    view["extensions"]["EXT_meshopt_compression"] = ext;
    fallback_size += m.stride * m.count;
  }
  json["buffers"].push_back({{"byteLength", fallback_size},
                             {"extensions", {{"EXT_meshopt_compression", {{"fallback", true}}}}}});
  for (const char* key : {"extensionsUsed", "extensionsRequired"}) {
    nlohmann::json& list = json[key];
    if (std::find(list.begin(), list.end(), "EXT_meshopt_compression") == list.end())
      list.push_back("EXT_meshopt_compression");
  }
  std::string text = json.dump();
  text.resize((text.size() + 3) / 4 * 4, ' ');
  std::string out = "glTF";
  append_u32(&out, 2);
  append_u32(&out, static_cast<std::uint32_t>(12 + 8 + text.size() + bin.size()));
  append_u32(&out, static_cast<std::uint32_t>(text.size()));
  out += "JSON";
  out += text;
  out += bin;
  return out;
}

}  // namespace

void write_glb(const std::filesystem::path& path, tinygltf::Model& model,
               std::span<const MeshoptView> meshopt) {
  tinygltf::TinyGLTF writer;
  std::ostringstream bytes;
  if (!writer.WriteGltfSceneToStream(&model, bytes, false, true))
    throw IoError(fmt::format("cannot serialise the glTF model for {}", path.string()));
  write_file_atomic(path, meshopt.empty() ? bytes.str() : add_meshopt_extension(bytes.str(), meshopt));
}

tinygltf::Model read_gltf(const std::filesystem::path& path) {
  const std::string file = path.string();
  const std::string bytes = read_file(path);
  tinygltf::TinyGLTF loader;
  tinygltf::Model model;
  loader.SetImageLoader(decode_image, &model);
  std::string err, warn;
  const auto* data = reinterpret_cast<const unsigned char*>(bytes.data());
  const bool binary = bytes.size() >= 4 && bytes.compare(0, 4, "glTF") == 0;
  const std::string base_dir = path.parent_path().string();
  const bool ok = binary
                      ? loader.LoadBinaryFromMemory(&model, &err, &warn, data,
                                                    static_cast<unsigned>(bytes.size()), base_dir)
                      : loader.LoadASCIIFromString(&model, &err, &warn, bytes.data(),
                                                   static_cast<unsigned>(bytes.size()), base_dir);
  if (!ok) {
    while (!err.empty() && err.back() == '\n') err.pop_back();
    throw InputError(
        fmt::format("{}: not a readable glTF file: {}", file, err.empty() ? "unknown error" : err));
  }
  return model;
}

}  // namespace fourd::gltf
