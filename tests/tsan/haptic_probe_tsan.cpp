// HapticProbe under ThreadSanitizer (tests/CMakeLists.txt, GF_TSAN_PROBE): a flat-out publisher
// and poller, then a 1 kHz poller beside a 60 Hz publisher. Exits non-zero on a torn record;
// TSan reports any data race and makes the exit code non-zero too.
#include <cstdio>

#include "common/haptic_stress.h"

int main() {
  int failures = 0;
  const struct {
    const char* name;
    double pollHz, publishHz;
  } runs[] = {{"flat out", 0, 0}, {"1 kHz poll, 60 Hz publish", 1000, 60}};
  for (const auto& run : runs) {
    const gf::test::ProbeStress r = gf::test::stressProbe(0.5, run.pollHz, run.publishHz);
    std::printf(
        "%s: %lld polls (%.0f Hz), %lld publishes, %lld fresh, %lld torn; poll median %.0f ns, "
        "p99 %.0f ns\n",
        run.name, (long long)r.polls, r.pollRateHz, (long long)r.publishes, (long long)r.fresh,
        (long long)r.torn, r.pollMedianNs, r.pollP99Ns);
    if (r.torn != 0 || r.fresh < 20) ++failures;
  }
  return failures;
}
