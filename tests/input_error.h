#pragma once
// The message of the error a piece of code throws, for tests that check what it names.
#include <gtest/gtest.h>

#include <string>

#include "pipeline/core/error.h"

namespace fourd::test {

// Message of the InputError `f` throws ("" and a test failure when it throws none).
template <class F>
std::string input_error(F&& f) {
  try {
    f();
  } catch (const InputError& e) {
    return e.what();
  }
  ADD_FAILURE() << "no InputError thrown";
  return "";
}

}  // namespace fourd::test
