#include "runtime/asset.h"

#include <fmt/format.h>

#include <cstdint>
#ifndef FOURD_ENCODED_TEXTURES
#include <opencv2/imgcodecs.hpp>
#endif

#include "pipeline/core/binary_format.h"
#include "pipeline/core/error.h"
#include "pipeline/core/files.h"
#include "pipeline/core/gzip.h"
#include "runtime/asset_packing.h"

namespace fourd {

namespace {

constexpr FileMagic kAssetMagic("FOURDAS");

// Bounds on counts read from a file, so a corrupt count fails with a message instead of a huge
// allocation (the reader also checks every array against the bytes left).
constexpr std::uint64_t kMaxSpaces = 1024;
constexpr std::uint64_t kMaxEdges = 1024 * 1024;
constexpr std::uint64_t kMaxTextureImages = 1 << 16;

// A node: the motion space (its own file's layout) followed by its normals: the inputs' in
// float, the other references' as fp16 displacements (before version 4: every reference's in
// float, converted at load like the positions).
// (version 6) A byte says how the geometry (frames, displacements, normals) is stored: 0 as
// above, 1 packed (runtime/asset_packing.h): the motion space's fields with empty frames and
// displacements, empty normals, then the packed geometry.
void write_space(BinaryWriter& w, const GraphSpace& g, const AssetPacking* packing) {
  w.write<std::uint8_t>(packing != nullptr ? 1 : 0);
  if (packing != nullptr) {
    MotionSpace shell = g.motion;
    shell.blend.frames.clear();
    shell.blend.displacements.clear();
    write_motion_space_fields(w, shell);
    w.write_span(std::span<const float>());
    w.write_span(std::span<const std::uint16_t>());
    write_packed_geometry(w, g, *packing);
  } else {
    write_motion_space_fields(w, g.motion);
    w.write_span(std::span<const float>(g.normals.data(), g.normals.size()));
    w.write_span(std::span<const std::uint16_t>(g.normal_displacements.data(),
                                                g.normal_displacements.size()));
  }
}

GraphSpace read_space(BinaryReader& r) {
  GraphSpace g;
  const std::uint8_t packed = r.version() >= kAssetVersionPacked ? r.read<std::uint8_t>() : 0;
  if (packed > 1) {
    throw InputError(fmt::format("{}: unknown geometry encoding {}", r.path().string(), packed));
  }
  const bool displacements = r.version() >= kAssetVersionDisplacements;
  g.motion = read_motion_space_fields(r, {.arc_angles = true, .displacements = displacements});
  if (packed == 1) {
    if (!g.motion.blend.frames.empty() || !g.motion.blend.displacements.empty() ||
        !read_aligned<float>(r, "normals").empty() ||
        !read_aligned<std::uint16_t>(r, "normal displacements").empty()) {
      throw InputError(fmt::format("{}: motion space '{}' is packed but also stores plain frames",
                                   r.path().string(), g.motion.name));
    }
    read_packed_geometry(r, &g);
  } else if (displacements) {
    g.normals = read_aligned<float>(r, "normals");
    g.normal_displacements = read_aligned<std::uint16_t>(r, "normal displacements");
  } else {
    const AlignedFloats all = read_aligned<float>(r, "normals");
    try {
      split_reference_frames(g.motion.blend, all, &g.normals, &g.normal_displacements);
    } catch (const InputError& e) {
      throw InputError(fmt::format("{}: normals of motion space '{}': {}", r.path().string(),
                                   g.motion.name, e.what()));
    }
  }
  return g;
}

void write_edge(BinaryWriter& w, const GraphEdge& e) {
  w.write<std::int32_t>(e.from);
  w.write<std::int32_t>(e.to);
  w.write<std::uint8_t>(e.self_loop ? 1 : 0);
  const EdgeSimilarity& s = e.similarity;
  w.write<std::int32_t>(s.source_inputs);
  w.write<std::int32_t>(s.target_inputs);
  w.write<std::int32_t>(s.source_samples);
  w.write<std::int32_t>(s.target_samples);
  w.write<double>(s.max_distance);
  w.write_vector(s.values);
  w.write_vector(e.precomputed);
}

GraphEdge read_edge(BinaryReader& r) {
  GraphEdge e;
  e.from = r.read<std::int32_t>();
  e.to = r.read<std::int32_t>();
  e.self_loop = r.read<std::uint8_t>() != 0;
  EdgeSimilarity& s = e.similarity;
  s.source_inputs = r.read<std::int32_t>();
  s.target_inputs = r.read<std::int32_t>();
  s.source_samples = r.read<std::int32_t>();
  s.target_samples = r.read<std::int32_t>();
  s.max_distance = r.read<double>();
  s.values = r.read_vector<float>();
  e.precomputed = r.read_vector<PrecomputedTransition>();
  return e;
}

void write_textures(BinaryWriter& w, const AssetTextures& t) {
  w.write<std::uint8_t>(t.empty() ? 0 : 1);
  if (t.empty()) return;
  w.write<std::int32_t>(t.width);
  w.write<std::int32_t>(t.height);
  w.write<std::int32_t>(t.jpeg_quality);
  w.write_vector(t.corner_uvs);
  w.write<std::uint64_t>(t.spaces.size());
  for (const SpaceTextures& s : t.spaces) w.write<std::int32_t>(s.keys);
  w.write<std::uint64_t>(t.images.size());
#ifndef FOURD_ENCODED_TEXTURES
  std::vector<std::uint8_t> bytes;
  for (std::size_t k = 0; k < t.images.size(); ++k) {
    if (!cv::imencode(".jpg", t.images[k], bytes, {cv::IMWRITE_JPEG_QUALITY, t.jpeg_quality})) {
      throw IoError(fmt::format("asset: key texture {} cannot be encoded as JPEG", k));
    }
    w.write_vector(bytes);
  }
#else
  for (const std::vector<std::uint8_t>& bytes : t.images) w.write_vector(bytes);  // JPEG files
#endif
}

// The image size a JPEG file announces in its frame header (SOFn), read before decoding so a
// corrupt file cannot make the decoder allocate more than the asset announces. False when the
// bytes are not a JPEG or have no frame header.
bool jpeg_size(const std::vector<std::uint8_t>& b, int* width, int* height) {
  if (b.size() < 4 || b[0] != 0xFF || b[1] != 0xD8) return false;
  std::size_t i = 2;
  while (i + 4 <= b.size()) {
    if (b[i] != 0xFF) return false;
    const std::uint8_t marker = b[i + 1];
    if (marker == 0xFF) {  // fill byte
      ++i;
      continue;
    }
    const std::size_t length = (static_cast<std::size_t>(b[i + 2]) << 8) | b[i + 3];
    const bool sof = marker >= 0xC0 && marker <= 0xCF && marker != 0xC4 && marker != 0xC8 &&
                     marker != 0xCC;
    if (sof) {
      if (length < 7 || i + 9 > b.size()) return false;
      *height = (b[i + 5] << 8) | b[i + 6];
      *width = (b[i + 7] << 8) | b[i + 8];
      return true;
    }
    if (marker == 0xD9 || marker == 0xDA || length < 2) return false;  // no frame header
    i += 2 + length;
  }
  return false;
}

AssetTextures read_textures(BinaryReader& r, std::size_t spaces) {
  AssetTextures t;
  if (r.read<std::uint8_t>() == 0) return t;
  const std::string file = r.path().string();
  t.width = r.read<std::int32_t>();
  t.height = r.read<std::int32_t>();
  t.jpeg_quality = r.read<std::int32_t>();
  if (t.width < 1 || t.height < 1 || t.width > 16384 || t.height > 16384) {
    throw InputError(fmt::format("{}: textures of {} x {} texels", file, t.width, t.height));
  }
  t.corner_uvs = r.read_vector<Vec2f>();
  const auto count = r.read<std::uint64_t>();
  if (count != spaces) {
    throw InputError(fmt::format("{}: key textures for {} spaces, the graph has {}", file, count,
                                 spaces));
  }
  for (std::uint64_t s = 0; s < count; ++s) {
    SpaceTextures st;
    st.keys = r.read<std::int32_t>();  // `first` follows from the inputs: set by load_asset
    if (st.keys < 0 || st.keys > 4096) {
      throw InputError(fmt::format("{}: space {} announces {} key textures", file, s, st.keys));
    }
    t.spaces.push_back(st);
  }
  const auto images = r.read<std::uint64_t>();
  if (images > kMaxTextureImages) {
    throw InputError(fmt::format("{}: {} key textures announced", file, images));
  }
  for (std::uint64_t k = 0; k < images; ++k) {
    const std::vector<std::uint8_t> bytes = r.read_vector<std::uint8_t>();
    int w = 0, h = 0;
    if (!jpeg_size(bytes, &w, &h)) {
      throw InputError(fmt::format("{}: key texture {} of {} is not a JPEG image ({} bytes)",
                                   file, k, images, bytes.size()));
    }
    if (w != t.width || h != t.height) {
      throw InputError(fmt::format("{}: key texture {} is {} x {}, the asset announces {} x {}",
                                   file, k, w, h, t.width, t.height));
    }
#ifdef FOURD_ENCODED_TEXTURES
    t.images.push_back(bytes);  // the browser decodes them
#else
    cv::Mat image;
    try {
      image = cv::imdecode(bytes, cv::IMREAD_COLOR);
    } catch (const cv::Exception&) {
      image.release();
    }
    if (image.empty()) {
      throw InputError(fmt::format("{}: key texture {} of {} is not a decodable image ({} bytes)",
                                   file, k, images, bytes.size()));
    }
    if (image.cols != t.width || image.rows != t.height) {
      throw InputError(fmt::format("{}: key texture {} is {} x {}, the asset announces {} x {}",
                                   file, k, image.cols, image.rows, t.width, t.height));
    }
    t.images.push_back(image);
#endif
  }
  return t;
}

}  // namespace

namespace {

BinaryWriter asset_payload(const Asset& asset, const AssetPacking* packing) {
  const MotionGraph& g = asset.graph;
  g.check();
  asset.transitions.check();
  BinaryWriter w;
  std::size_t bytes = 4096;
  for (const GraphSpace& s : g.spaces) {
    bytes += 2 * (s.normals.size() * sizeof(float) +
                  s.normal_displacements.size() * sizeof(std::uint16_t)) +
             4096;
  }
  for (const GraphEdge& e : g.edges) bytes += e.similarity.values.size() * sizeof(float) + 1024;
  w.reserve(bytes);
  w.write_string(g.name);
  w.write<double>(g.fps);
  w.write<double>(g.similarity.velocity_weight);
  w.write<double>(g.similarity.frame_time);
  const TransitionOptions& t = asset.transitions;
  w.write<double>(t.alpha);
  w.write<double>(t.lambda);
  w.write<std::int32_t>(t.depth);
  w.write<double>(t.cost_unit);
  w.write<double>(t.one_shot_target_t);
  w.write<std::uint64_t>(g.spaces.size());
  for (const GraphSpace& s : g.spaces) write_space(w, s, packing);
  w.write<std::uint64_t>(g.edges.size());
  for (const GraphEdge& e : g.edges) write_edge(w, e);
  for (const GraphSpace& s : g.spaces) w.write<std::int32_t>(s.default_successor);
  write_textures(w, g.textures);
  return w;
}

}  // namespace

void save_asset(const std::filesystem::path& path, const Asset& asset) {
  asset_payload(asset, nullptr).save(path, kAssetMagic, kAssetVersion);
}

void save_web_package(const std::filesystem::path& path, const Asset& asset,
                      const AssetPacking& packing) {
  packing.check();
#ifdef FOURD_NO_ZLIB
  (void)asset;
  throw Error(fmt::format("{}: this build writes no web packages (no zlib)", path.string()));
#else
  const std::string bytes = asset_payload(asset, &packing).file_bytes(kAssetMagic, kAssetVersion);
  write_file_atomic(path, gzip_compress(bytes));
#endif
}

Asset load_asset(const std::filesystem::path& path) {
  std::string bytes = read_file(path);
  if (is_gzip(bytes)) {  // a web package
#ifdef FOURD_NO_ZLIB
    throw InputError(fmt::format("{}: gzip-compressed (a web package): inflate it before loading "
                                 "(the web page does, with DecompressionStream)",
                                 path.string()));
#else
    bytes = gzip_decompress(bytes, path.string());
#endif
  }
  static constexpr std::uint32_t kVersions[] = {2, 3, kAssetVersionDisplacements,
                                                  kAssetVersionSuccessors, kAssetVersion};
  BinaryReader r = BinaryReader::from_bytes(path, std::move(bytes), kAssetMagic, kVersions);
  Asset asset;
  MotionGraph& g = asset.graph;
  g.name = r.read_string();
  g.fps = r.read<double>();
  g.similarity.velocity_weight = r.read<double>();
  g.similarity.frame_time = r.read<double>();
  TransitionOptions& t = asset.transitions;
  t.alpha = r.read<double>();
  t.lambda = r.read<double>();
  t.depth = r.read<std::int32_t>();
  t.cost_unit = r.read<double>();
  t.one_shot_target_t = r.read<double>();
  const auto spaces = r.read<std::uint64_t>();
  if (spaces > kMaxSpaces) {
    throw InputError(fmt::format("{}: {} motion spaces announced", path.string(), spaces));
  }
  for (std::uint64_t k = 0; k < spaces; ++k) g.spaces.push_back(read_space(r));
  const auto edges = r.read<std::uint64_t>();
  if (edges > kMaxEdges) {
    throw InputError(fmt::format("{}: {} edges announced", path.string(), edges));
  }
  for (std::uint64_t k = 0; k < edges; ++k) g.edges.push_back(read_edge(r));
  if (r.version() >= kAssetVersionSuccessors) {
    for (GraphSpace& s : g.spaces) s.default_successor = r.read<std::int32_t>();
  } else {
    choose_default_successors(&g);
  }
  if (r.version() >= 3) {
    g.textures = read_textures(r, g.spaces.size());
    // Image offsets from the spaces' input counts (the file stores only the key counts).
    int first = 0;
    for (std::size_t s = 0; s < g.textures.spaces.size(); ++s) {
      g.textures.spaces[s].first = first;
      first += g.textures.spaces[s].keys * g.spaces[s].num_inputs();
    }
  }
  r.expect_end();
  try {
    g.check();
    t.check();
  } catch (const Error& e) {
    throw InputError(fmt::format("{}: {}", path.string(), e.what()));
  }
  return asset;
}

}  // namespace fourd
