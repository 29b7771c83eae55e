#include "cli/progress.h"

#include <unistd.h>

#include <algorithm>
#include <cmath>

namespace gf::cli {

Progress::Mode Progress::detect(std::FILE* stream, bool quiet) {
  if (quiet) return Mode::Off;
  return isatty(fileno(stream)) ? Mode::Bar : Mode::Lines;
}

Progress::Progress(int total, Mode mode, std::FILE* stream)
    : m_total(std::max(total, 1)), m_mode(mode), m_stream(stream), m_start(Clock::now()) {
  m_lastDraw = m_start;
}

std::string formatDuration(double seconds) {
  char buf[32];
  if (!std::isfinite(seconds) || seconds < 0) return "?";
  if (seconds < 60) {
    std::snprintf(buf, sizeof buf, "%.1f s", seconds);
  } else {
    const long s = std::lround(seconds);
    std::snprintf(buf, sizeof buf, "%ld:%02ld", s / 60, s % 60);
  }
  return buf;
}

void Progress::update(int done, const std::string& note) {
  m_lastDone = done;
  m_lastNote = note;
  if (m_mode == Mode::Off) return;
  const Clock::time_point now = Clock::now();
  const double sinceDraw = std::chrono::duration<double>(now - m_lastDraw).count();
  if (m_mode == Mode::Bar) {
    // Redrawing every frame of a fast scene would cost more than the frame; 20 Hz reads well.
    if (m_drawn && sinceDraw < 0.05 && done < m_total) return;
  } else {
    // Plain lines: every 10 % or every 10 s, whichever comes first.
    const int step = done * 10 / m_total;
    if (step <= m_lastPercentLine && sinceDraw < 10 && done < m_total) return;
    m_lastPercentLine = step;
  }
  m_lastDraw = now;
  draw(done, note, false);
}

void Progress::draw(int done, const std::string& note, bool final) {
  const double elapsed = std::chrono::duration<double>(Clock::now() - m_start).count();
  const double frac = std::clamp(static_cast<double>(done) / m_total, 0.0, 1.0);
  const double eta = done > 0 ? elapsed * (m_total - done) / done : NAN;
  char counts[96];
  std::snprintf(counts, sizeof counts, "%d/%d  %s  ETA %s", done, m_total,
                formatDuration(elapsed).c_str(), final ? "-" : formatDuration(eta).c_str());
  if (m_mode == Mode::Bar) {
    constexpr int kWidth = 28;
    const int filled = static_cast<int>(std::lround(frac * kWidth));
    std::string bar(filled, '#');
    bar.resize(kWidth, '.');
    // \r + clear-to-end-of-line keeps the bar on one line as the note changes length.
    std::fprintf(m_stream, "\r\033[K%3.0f%% [%s] %s  %s", frac * 100, bar.c_str(), counts,
                 note.c_str());
  } else {
    std::fprintf(m_stream, "%3.0f%%  %s  %s\n", frac * 100, counts, note.c_str());
  }
  std::fflush(m_stream);
  m_drawn = true;
}

void Progress::finish() {
  if (m_mode == Mode::Off) return;
  if (m_mode == Mode::Bar) {
    draw(m_lastDone, m_lastNote, true);
    std::fputc('\n', m_stream);
  } else if (m_lastPercentLine < 10) {
    draw(m_lastDone, m_lastNote, true);
  }
  std::fflush(m_stream);
}

}  // namespace gf::cli
