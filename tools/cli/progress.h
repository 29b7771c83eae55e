// Progress display of a long run: a bar redrawn in place on a terminal, occasional plain lines
// when stderr is a file or a pipe (CI logs), nothing when quiet.
#pragma once

#include <time.h>

#include <chrono>
#include <cstdio>
#include <string>

namespace gf::cli {

/// Reports frames done out of a total on a stream (stderr by default).
class Progress {
 public:
  enum class Mode { Off, Bar, Lines };

  /// Bar when `stream` is a terminal, Lines otherwise; Off when quiet.
  static Mode detect(std::FILE* stream, bool quiet);

  Progress(int total, Mode mode, std::FILE* stream = stderr);
  /// `done` frames are complete; `note` is a short status shown after the counters.
  void update(int done, const std::string& note);
  /// Ends the bar line (or prints a last line) so that later output starts clean.
  void finish();

 private:
  void draw(int done, const std::string& note, bool final);

  using Clock = std::chrono::steady_clock;
  int m_total;
  Mode m_mode;
  std::FILE* m_stream;
  Clock::time_point m_start;
  Clock::time_point m_lastDraw;
  int m_lastPercentLine = -1;  // Lines mode: the last 10 % step printed
  int m_lastDone = 0;
  std::string m_lastNote;
  bool m_drawn = false;
};

/// "1:05" or "12.3 s" style duration for humans.
std::string formatDuration(double seconds);

/// Wall-clock milliseconds since t0 on the steady clock: the one stopwatch of the tools (frame
/// timings of BulletScene, the demo, the benchmarks). Inline so that the scene library can use
/// it without linking the CLI.
inline double msSince(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

/// CPU time of the whole process [ms]: on a shared machine other jobs stretch the wall clock but
/// not this, so the ranking of settings survives a noisy machine. It sums all threads (the
/// thread pool's and BLAS's), so with several threads it exceeds the wall clock.
inline double processCpuMs() {
  timespec ts{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
  return 1e3 * static_cast<double>(ts.tv_sec) + 1e-6 * static_cast<double>(ts.tv_nsec);
}

}  // namespace gf::cli
