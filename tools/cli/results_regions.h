// Generated regions of a hand-written markdown file (docs/RESULTS.md): `graphfrac report all`
// owns only the lines between `<!-- report:NAME:begin -->` and `<!-- report:NAME:end -->`;
// every other byte of the file, the marker lines included, is the authors' and is written back
// unchanged. The markers are HTML comments, so they do not show in rendered markdown.
#pragma once

#include <graphfrac/status.h>

#include <map>
#include <string>
#include <vector>

namespace gf::cli {

/// A marked file split into the authors' text and the generated regions.
struct MarkedText {
  /// Alternating pieces: text[0], region 0, text[1], region 1, ..., text[n]. text[i] ends with
  /// region i's begin marker line, text[i + 1] starts with its end marker line.
  std::vector<std::string> text;
  std::vector<std::string> names;     ///< Region names, in file order.
  std::vector<std::string> contents;  ///< Region bodies (whole lines), in file order.
};

/// The marker line of a region, without its line break.
std::string regionMarker(const std::string& name, bool begin);

/// Splits `content` (the text of `path`, which only names it in errors) into its regions.
/// Every name in `known` must have exactly one begin and one end marker, in that order, not
/// nested in another region; a marker naming anything else is an error. Errors name the file,
/// the region and the line.
Result<MarkedText> parseMarkedText(const std::string& path, const std::string& content,
                                   const std::vector<std::string>& known);

/// Joins `marked` back, with each region named in `replace` given its new body (a line break
/// is added when the body does not end in one); the other regions keep theirs.
std::string spliceRegions(const MarkedText& marked,
                          const std::map<std::string, std::string>& replace);

}  // namespace gf::cli
