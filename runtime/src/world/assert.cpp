// The replaceable assertion handler behind GF_ASSERT.
#include <atomic>
#include <cstdio>
#include <cstdlib>

#include "graphfrac/status.h"

namespace gf {

namespace {
void defaultHandler(const char* condition, const char* message, const char* file, int line) {
  std::fprintf(stderr, "graphfrac: assertion failed at %s:%d: %s (%s)\n", file, line, message,
               condition);
  std::abort();
}
std::atomic<AssertHandler> g_handler{&defaultHandler};
}  // namespace

AssertHandler setAssertHandler(AssertHandler handler) {
  return g_handler.exchange(handler ? handler : &defaultHandler);
}

namespace detail {
void assertFailed(const char* condition, const char* message, const char* file, int line) {
  g_handler.load()(condition, message, file, line);
}
}  // namespace detail

}  // namespace gf
