#pragma once
// The one way a fourd executable turns a failure into its exit code: run the tool's work and,
// if it throws, log "<tool>: <message>" and return the error's code (an unexpected exception is
// an internal error, kExitFailure).
#include <functional>
#include <string_view>

namespace fourd {

int run_guarded(std::string_view tool, const std::function<int()>& body);

}  // namespace fourd
