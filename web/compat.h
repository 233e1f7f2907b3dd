#pragma once
// Forced into every file of the web build (-include): what the C++20 library of Debian's
// Emscripten 3.1.6 (libc++ 13) lacks and the runtime uses. Nothing here reaches the native build.
#include <bit>
#include <charconv>
#include <cstdlib>
#include <string>
#include <system_error>
#include <type_traits>

#if !defined(__cpp_lib_bit_cast)
namespace std {
template <class To, class From>
  requires(sizeof(To) == sizeof(From) && is_trivially_copyable_v<To> &&
           is_trivially_copyable_v<From>)
constexpr To bit_cast(const From& from) noexcept {
  return __builtin_bit_cast(To, from);
}
}  // namespace std
#endif

#if defined(_LIBCPP_VERSION) && _LIBCPP_VERSION < 14000
namespace std {
// from_chars for float and double (control scripts, PLY headers): strtod on a bounded copy, with
// from_chars' contract (no leading whitespace or '+', the end of what was read, errc).
template <class T>
  requires(is_same_v<T, double> || is_same_v<T, float>)
from_chars_result from_chars(const char* first, const char* last, T& value) {
  const string text(first, last);
  if (text.empty() || text[0] == '+' || isspace(static_cast<unsigned char>(text[0]))) {
    return {first, errc::invalid_argument};
  }
  char* end = nullptr;
  const T v = is_same_v<T, float> ? strtof(text.c_str(), &end) : strtod(text.c_str(), &end);
  if (end == text.c_str()) return {first, errc::invalid_argument};
  value = v;
  return {first + (end - text.c_str()), errc()};
}
}  // namespace std
#endif
