#pragma once
// gzip (RFC 1952) in memory, with zlib: the web package of an asset (runtime/asset_packing.h) is
// a gzip file the browser inflates with its own DecompressionStream. The web build compiles no
// gzip.cpp (no zlib there: the page inflates before the module reads the file); is_gzip is
// header-only so its loader can still tell a package from a plain asset.
#include <cstddef>
#include <string>
#include <string_view>

namespace fourd {

// Whether `bytes` start with gzip's magic (1f 8b).
inline bool is_gzip(std::string_view bytes) {
  return bytes.size() >= 2 && static_cast<unsigned char>(bytes[0]) == 0x1f &&
         static_cast<unsigned char>(bytes[1]) == 0x8b;
}
// One gzip member holding `bytes` (level 1..9).
std::string gzip_compress(std::string_view bytes, int level = 9);
// The bytes of a gzip file (every member, concatenated). Throws InputError naming `name` when
// the data is not gzip, is corrupt or truncated, or inflates beyond `max_bytes`.
std::string gzip_decompress(std::string_view bytes, const std::string& name,
                            std::size_t max_bytes = std::size_t{1} << 31);

}  // namespace fourd
