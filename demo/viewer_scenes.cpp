// graphfrac-viewer's scene picker: the scenes offered next to the running one and how a name
// picked in the panel or given to a script's `scene` command becomes a file.
#include <algorithm>
#include <filesystem>
#include <system_error>

#include "viewer_app.h"

namespace gf::demo {

namespace fs = std::filesystem;

std::vector<std::string> siblingScenes(const std::string& scene) {
  std::vector<std::string> out;
  std::error_code ec;
  const fs::path dir = fs::path(scene).parent_path();
  for (const fs::directory_entry& e :
       fs::directory_iterator(dir.empty() ? fs::path(".") : dir, ec)) {
    if (e.path().extension() == ".json") out.push_back(e.path().string());
  }
  std::sort(out.begin(), out.end());
  return out;
}

std::string resolveScene(const std::string& name, std::span<const std::string> offered) {
  // A bare name means the picker's entry: the script then reads like a click in the list, and
  // does not depend on the directory the viewer was started from.
  if (fs::path(name).has_parent_path()) return name;
  for (const std::string& f : offered) {
    const fs::path p(f);
    if (p.filename() == name || p.stem() == name) return f;
  }
  return name;
}

}  // namespace gf::demo
