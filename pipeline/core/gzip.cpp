#include "pipeline/core/gzip.h"

#include <fmt/format.h>
#include <zlib.h>

#include <algorithm>

#include "pipeline/core/error.h"

namespace fourd {

namespace {

constexpr int kGzipWindow = 15 + 16;  // zlib's window bits for the gzip wrapper
constexpr std::size_t kChunk = std::size_t{1} << 20;

}  // namespace

std::string gzip_compress(std::string_view bytes, int level) {
  z_stream z{};
  if (deflateInit2(&z, std::clamp(level, 1, 9), Z_DEFLATED, kGzipWindow, 9, Z_DEFAULT_STRATEGY) !=
      Z_OK) {
    throw Error("gzip: zlib's deflate cannot start");
  }
  std::string out(deflateBound(&z, static_cast<uLong>(bytes.size())), '\0');
  z.next_in = reinterpret_cast<Bytef*>(const_cast<char*>(bytes.data()));
  z.avail_in = static_cast<uInt>(bytes.size());
  z.next_out = reinterpret_cast<Bytef*>(out.data());
  z.avail_out = static_cast<uInt>(out.size());
  const int status = deflate(&z, Z_FINISH);
  const std::size_t written = z.total_out;
  deflateEnd(&z);
  if (status != Z_STREAM_END) throw Error(fmt::format("gzip: deflate failed ({})", status));
  out.resize(written);
  return out;
}

std::string gzip_decompress(std::string_view bytes, const std::string& name, std::size_t max_bytes) {
  if (!is_gzip(bytes)) throw InputError(fmt::format("{}: not a gzip file", name));
  std::string out;
  std::size_t at = 0;
  while (at < bytes.size()) {  // one member after another (RFC 1952 allows several)
    z_stream z{};
    if (inflateInit2(&z, kGzipWindow) != Z_OK) throw Error("gzip: zlib's inflate cannot start");
    z.next_in = reinterpret_cast<Bytef*>(const_cast<char*>(bytes.data() + at));
    z.avail_in = static_cast<uInt>(bytes.size() - at);
    int status = Z_OK;
    while (status == Z_OK) {
      if (out.size() >= max_bytes) {
        inflateEnd(&z);
        throw InputError(fmt::format("{}: gzip data inflates beyond {} bytes", name, max_bytes));
      }
      const std::size_t before = out.size();
      out.resize(std::min(max_bytes, before + kChunk));
      z.next_out = reinterpret_cast<Bytef*>(out.data() + before);
      z.avail_out = static_cast<uInt>(out.size() - before);
      status = inflate(&z, Z_NO_FLUSH);
      out.resize(out.size() - z.avail_out);
      if (status == Z_BUF_ERROR && z.avail_in == 0) break;  // input ends inside the stream
      if (status == Z_BUF_ERROR) status = Z_OK;             // output was full: go on
    }
    const std::size_t consumed = bytes.size() - at - z.avail_in;
    const std::string message = z.msg != nullptr ? z.msg : fmt::format("zlib status {}", status);
    inflateEnd(&z);
    if (status != Z_STREAM_END) {
      throw InputError(fmt::format("{}: corrupt or truncated gzip data ({})", name, message));
    }
    at += consumed;
    while (at < bytes.size() && bytes[at] == '\0') ++at;  // padding after the last member
  }
  return out;
}

}  // namespace fourd
