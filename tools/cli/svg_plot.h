// A small SVG scatter-plot writer for the reports: labelled points in coloured series, linear
// or logarithmic axes, several panels side by side. No plotting package is needed to read the
// figures the project checks in.
#pragma once

#include <graphfrac/status.h>

#include <string>
#include <vector>

namespace gf::cli {

struct PlotPoint {
  double x = 0, y = 0;
  std::string label;  ///< Drawn next to the point (may be empty).
};

struct PlotSeries {
  std::string name;  ///< Legend entry.
  std::string colour;
  std::vector<PlotPoint> points;
  /// Joins the points, in order, by a line instead of drawing each (curves of many samples).
  bool line = false;
};

struct PlotPanel {
  std::string title, xLabel, yLabel;
  bool logX = false, logY = false;  ///< Log axes drop points with a value <= 0 (listed in a note).
  std::vector<PlotSeries> series;
};

/// Renders the panels side by side, each width x height pixels, with `caption` underneath.
std::string renderSvg(const std::vector<PlotPanel>& panels, const std::string& caption,
                      int width = 560, int height = 420);

/// Writes renderSvg(...) to `path`.
Result<void> writeSvg(const std::string& path, const std::vector<PlotPanel>& panels,
                      const std::string& caption);

}  // namespace gf::cli
