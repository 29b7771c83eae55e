// What graphfrac-viewer's ImGui panel reports, apart from ImGui: the figures it shows and the
// text lines it draws them as. The panel draws exactly these lines, and a script's `panel`
// command writes them to a file, so a test reads what a user reads.
#pragma once

#include <graphfrac/defs.h>
#include <graphfrac/status.h>

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "scene/bullet_scene.h"

namespace gf::demo {

/// The material of the body picked last (by a drag), as the scene defines it.
struct PickedMaterial {
  std::string body;
  Material material;
  FractureSettings fracture;
};

struct PanelFigures {
  int frame = 0;  ///< Steps taken on the running scene.
  double dt = 0;  ///< The scene's step [s].
  scene::FrameTimings timings;
  StepStatus lastStep;  ///< The last step's solver figures.
  int64_t fragments = 0, brokenEdges = 0, edgeCount = 0;
  size_t handedOff = 0;  ///< Fragments handed to Bullet.
  std::optional<PickedMaterial> picked;
};

/// The panel's figures of a running scene now (fragments and edges summed over its bodies as
/// `graphfrac run` counts them: a body without fracture is one fragment).
PanelFigures panelFigures(const scene::BulletScene& sim, double dt, const StepStatus& lastStep,
                          std::optional<PickedMaterial> picked);

/// The panel's text, a line each; an empty line stands for a separator.
std::vector<std::string> panelLines(const PanelFigures& f);

const char* materialModelName(MaterialModel m);

}  // namespace gf::demo
