#include "cli/svg_plot.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>

namespace gf::cli {
namespace {

std::string num(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.1f", v);
  return buf;
}

std::string tickText(double v) {
  char buf[32];
  if (v != 0 && (std::fabs(v) >= 1e4 || std::fabs(v) < 1e-2))
    std::snprintf(buf, sizeof buf, "%.0e", v);
  else
    std::snprintf(buf, sizeof buf, "%g", v);
  return buf;
}

std::string escape(const std::string& s) {
  std::string out;
  for (char c : s) {
    if (c == '<')
      out += "&lt;";
    else if (c == '>')
      out += "&gt;";
    else if (c == '&')
      out += "&amp;";
    else
      out += c;
  }
  return out;
}

// One axis: maps data to [0, 1] and lists tick values.
struct Axis {
  bool log = false;
  double lo = 0, hi = 1;

  void fit(double mn, double mx) {
    if (!(mn <= mx)) mn = mx = log ? 1 : 0;
    if (log) {
      lo = std::pow(10.0, std::floor(std::log10(mn)));
      hi = std::pow(10.0, std::ceil(std::log10(mx)));
      if (hi <= lo) hi = lo * 10;
    } else {
      const double pad = mx > mn ? 0.05 * (mx - mn) : (mn != 0 ? 0.1 * std::fabs(mn) : 1);
      lo = mn - pad;
      hi = mx + pad;
    }
  }
  double map(double v) const {
    return log ? (std::log10(v) - std::log10(lo)) / (std::log10(hi) - std::log10(lo))
               : (v - lo) / (hi - lo);
  }
  std::vector<double> ticks() const {
    std::vector<double> t;
    if (log) {
      for (double v = lo; v <= hi * 1.0001; v *= 10) t.push_back(v);
      return t;
    }
    const double raw = (hi - lo) / 5;
    const double mag = std::pow(10.0, std::floor(std::log10(raw)));
    const double step = raw / mag < 2 ? 2 * mag : raw / mag < 5 ? 5 * mag : 10 * mag;
    for (double v = std::ceil(lo / step) * step; v <= hi; v += step)
      t.push_back(std::fabs(v) < 1e-12 * step ? 0 : v);
    return t;
  }
};

void renderPanel(std::string& svg, const PlotPanel& p, double ox, int width, int height) {
  const double left = ox + 70, right = ox + width - 20, top = 40, bottom = height - 60;
  Axis ax, ay;
  ax.log = p.logX;
  ay.log = p.logY;
  double xmn = std::numeric_limits<double>::infinity(), xmx = -xmn, ymn = xmn, ymx = -xmn;
  int dropped = 0;
  for (const PlotSeries& s : p.series) {
    for (const PlotPoint& q : s.points) {
      if ((p.logX && !(q.x > 0)) || (p.logY && !(q.y > 0)) || !std::isfinite(q.x) ||
          !std::isfinite(q.y)) {
        ++dropped;
        continue;
      }
      xmn = std::min(xmn, q.x);
      xmx = std::max(xmx, q.x);
      ymn = std::min(ymn, q.y);
      ymx = std::max(ymx, q.y);
    }
  }
  ax.fit(xmn, xmx);
  ay.fit(ymn, ymx);
  auto px = [&](double v) { return left + ax.map(v) * (right - left); };
  auto py = [&](double v) { return bottom - ay.map(v) * (bottom - top); };

  svg += "<text x='" + num((left + right) / 2) + "' y='24' text-anchor='middle' font-size='15'>" +
         escape(p.title) + "</text>\n";
  svg += "<rect x='" + num(left) + "' y='" + num(top) + "' width='" + num(right - left) +
         "' height='" + num(bottom - top) + "' fill='none' stroke='#333'/>\n";
  for (double t : ax.ticks()) {
    const double x = px(t);
    svg += "<line x1='" + num(x) + "' y1='" + num(top) + "' x2='" + num(x) + "' y2='" +
           num(bottom) + "' stroke='#ddd'/>\n";
    svg += "<text x='" + num(x) + "' y='" + num(bottom + 16) +
           "' text-anchor='middle' font-size='11'>" + tickText(t) + "</text>\n";
  }
  for (double t : ay.ticks()) {
    const double y = py(t);
    svg += "<line x1='" + num(left) + "' y1='" + num(y) + "' x2='" + num(right) + "' y2='" +
           num(y) + "' stroke='#ddd'/>\n";
    svg += "<text x='" + num(left - 6) + "' y='" + num(y + 4) +
           "' text-anchor='end' font-size='11'>" + tickText(t) + "</text>\n";
  }
  svg += "<text x='" + num((left + right) / 2) + "' y='" + num(bottom + 36) +
         "' text-anchor='middle' font-size='12'>" + escape(p.xLabel) + "</text>\n";
  svg += "<text x='" + num(ox + 16) + "' y='" + num((top + bottom) / 2) +
         "' text-anchor='middle' font-size='12' transform='rotate(-90 " + num(ox + 16) + " " +
         num((top + bottom) / 2) + ")'>" + escape(p.yLabel) + "</text>\n";
  double legendY = top + 14;
  for (const PlotSeries& s : p.series) {
    std::string polyline;
    for (const PlotPoint& q : s.points) {
      if ((p.logX && !(q.x > 0)) || (p.logY && !(q.y > 0)) || !std::isfinite(q.x) ||
          !std::isfinite(q.y))
        continue;
      if (s.line) {
        polyline += num(px(q.x)) + "," + num(py(q.y)) + " ";
        continue;
      }
      // Dense clouds (crack maps) in small dots, so the pattern shows.
      svg += "<circle cx='" + num(px(q.x)) + "' cy='" + num(py(q.y)) + "' r='" +
             (s.points.size() > 200 ? "1.5" : "4") + "' fill='" + s.colour + "'/>\n";
      if (!q.label.empty())
        svg += "<text x='" + num(px(q.x) + 6) + "' y='" + num(py(q.y) - 4) +
               "' font-size='9' fill='#444'>" + escape(q.label) + "</text>\n";
    }
    if (s.line) {
      svg += "<polyline points='" + polyline + "' fill='none' stroke='" + s.colour +
             "' stroke-width='1.5'/>\n";
      svg += "<line x1='" + num(right - 158) + "' y1='" + num(legendY - 4) + "' x2='" +
             num(right - 146) + "' y2='" + num(legendY - 4) + "' stroke='" + s.colour +
             "' stroke-width='2'/>";
    } else {
      svg += "<circle cx='" + num(right - 150) + "' cy='" + num(legendY - 4) + "' r='4' fill='" +
             s.colour + "'/>";
    }
    svg += "<text x='" + num(right - 142) + "' y='" + num(legendY) + "' font-size='11'>" +
           escape(s.name) + "</text>\n";
    legendY += 15;
  }
  if (dropped > 0)
    svg += "<text x='" + num(left + 4) + "' y='" + num(bottom - 6) + "' font-size='10'>" +
           std::to_string(dropped) + " point(s) <= 0 not shown on the log axis</text>\n";
}

}  // namespace

std::string renderSvg(const std::vector<PlotPanel>& panels, const std::string& caption, int width,
                      int height) {
  const int total = width * static_cast<int>(std::max<size_t>(panels.size(), 1));
  std::string svg = "<svg xmlns='http://www.w3.org/2000/svg' width='" + std::to_string(total) +
                    "' height='" + std::to_string(height + 30) +
                    "' font-family='sans-serif'>\n<rect width='100%' height='100%' "
                    "fill='white'/>\n";
  for (size_t i = 0; i < panels.size(); ++i)
    renderPanel(svg, panels[i], static_cast<double>(i) * width, width, height);
  svg += "<text x='10' y='" + std::to_string(height + 18) + "' font-size='11'>" + escape(caption) +
         "</text>\n</svg>\n";
  return svg;
}

Result<void> writeSvg(const std::string& path, const std::vector<PlotPanel>& panels,
                      const std::string& caption) {
  const std::string svg = renderSvg(panels, caption);
  std::FILE* f = std::fopen(path.c_str(), "wb");
  if (!f) return fail(path, ": cannot open for writing");
  const bool ok = std::fwrite(svg.data(), 1, svg.size(), f) == svg.size();
  if (std::fclose(f) != 0 || !ok) return fail(path, ": write failed");
  return {};
}

}  // namespace gf::cli
