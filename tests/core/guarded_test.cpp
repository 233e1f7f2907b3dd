#include "pipeline/core/guarded.h"

#include <gtest/gtest.h>

#include <stdexcept>

#include "pipeline/core/error.h"

namespace fourd {
namespace {

TEST(RunGuarded, PassesTheBodysExitCodeThrough) {
  EXPECT_EQ(run_guarded("tool", [] { return 0; }), kExitOk);
  EXPECT_EQ(run_guarded("tool", [] { return 7; }), 7);
}

TEST(RunGuarded, TurnsTypedErrorsIntoTheirExitCodes) {
  EXPECT_EQ(run_guarded("tool", []() -> int { throw InputError("frame 3: empty mesh"); }),
            kExitInput);
  EXPECT_EQ(run_guarded("tool", []() -> int { throw IoError("cannot write x.ply"); }), kExitIo);
  EXPECT_EQ(run_guarded("tool", []() -> int { throw UsageError("two jobs"); }), kExitUsage);
}

TEST(RunGuarded, AnyOtherExceptionIsAnInternalFailure) {
  EXPECT_EQ(run_guarded("tool", []() -> int { throw std::runtime_error("bug"); }), kExitFailure);
}

}  // namespace
}  // namespace fourd
