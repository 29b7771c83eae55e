// Test entry point. A failed GF_ASSERT inside the runtime becomes a test failure (not an
// abort), so one broken invariant names itself and the remaining tests still run.
#include <graphfrac/status.h>
#include <gtest/gtest.h>

namespace {
void assertToFailure(const char* condition, const char* message, const char* file, int line) {
  ADD_FAILURE_AT(file, line) << "GF_ASSERT(" << condition << "): " << message;
}
}  // namespace

int main(int argc, char** argv) {
  ::testing::InitGoogleTest(&argc, argv);
  gf::setAssertHandler(&assertToFailure);
  return RUN_ALL_TESTS();
}
