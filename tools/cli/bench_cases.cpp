// The scene list shared by `bench multigrid` and `bench scenes` (cli/bench_cases.h).
#include "cli/bench_cases.h"

namespace gf::cli {

namespace {

// Strengths are set so that gravity or the grip reaches them in the first frames; the broken
// counts say whether they did.
const BenchCase kCases[] = {
    {"hinged beam", "320.9", R"({"strength": 2e4})", false, false,
     R"({"dt": 0.016666666666666666, "gravity": [0, -9.81, 0],
      "bodies": [{"name": "b", "mesh": {"generator": "box", "size": [1.0, 0.3, 0.3],
        "cells": [20, 6, 6]}, "material": {"model": "stable_neo_hookean", "E": 1e6, "nu": 0.4,
        "rho": 1000}, "solver": SOLVER FRACTURE,
        "pins": [{"region": {"min": [0, 0.3, 0], "max": [0, 0.3, 0.3]}}]}]})"},
    {"charpy bar", "152.5", R"({"strength": 4e8})", true, false,
     R"({"dt": 1e-5, "gravity": [0, 0, 0],
      "bodies": [{"name": "b", "mesh": {"generator": "box", "size": [0.055, 0.01, 0.01],
        "cells": [68, 12, 6], "notch": {"depth": 0.002, "angle_deg": 45}},
        "material": {"model": "corotated", "E": 2e11, "nu": 0.3, "rho": 7850},
        "solver": SOLVER FRACTURE,
        "pins": [{"region": {"min": [0.007, 0.01, 0], "max": [0.0078, 0.01, 0.01]}},
                 {"region": {"min": [0.0472, 0.01, 0], "max": [0.048, 0.01, 0.01]}}],
        "grips": [{"region": {"min": [0.0265, 0, 0], "max": [0.0285, 0, 0.01]},
                   "velocity": [0, 2, 0]}]}]})"},
    {"hanging sphere", "118.7", R"({"strength": 500})", false, false,
     R"({"dt": 0.016666666666666666, "gravity": [0, -9.81, 0],
      "bodies": [{"name": "b", "mesh": {"generator": "sphere", "radius": 0.1, "cells": 18},
        "material": {"model": "stable_neo_hookean", "E": 2e4, "nu": 0.45, "rho": 1000,
        "damping": {"mass": 0.5}}, "solver": SOLVER FRACTURE,
        "pins": [{"region": {"min": [-0.1, 0.09, -0.1], "max": [0.1, 0.1, 0.1]}}]}]})"},
    {"sphere 160k", "34.9", R"({"strength": 500})", false, false,
     R"({"dt": 0.016666666666666666, "gravity": [0, -9.81, 0],
      "bodies": [{"name": "b", "mesh": {"generator": "sphere", "radius": 0.1, "cells": 30},
        "material": {"model": "stable_neo_hookean", "E": 2e4, "nu": 0.45, "rho": 1000,
        "damping": {"mass": 0.5}}, "solver": SOLVER FRACTURE,
        "pins": [{"region": {"min": [-0.1, 0.095, -0.1], "max": [0.1, 0.1, 0.1]}}]}]})"},
    {"box 680k", nullptr, R"({"strength": 1e4})", false, true,
     R"({"dt": 0.016666666666666666, "gravity": [0, -9.81, 0],
      "bodies": [{"name": "b", "mesh": {"generator": "box", "size": [1.96, 0.68, 0.68],
        "cells": [98, 34, 34]}, "material": {"model": "stable_neo_hookean", "E": 1e7,
        "nu": 0.4, "rho": 1000}, "solver": SOLVER FRACTURE,
        "pins": [{"region": {"min": [0, 0, 0], "max": [0, 0.68, 0.68]}}]}]})"},
};

}  // namespace

std::span<const BenchCase> benchCases() { return kCases; }

std::string benchSceneText(const BenchCase& c, const std::string& solver, bool fracture) {
  std::string text = c.scene;
  text.replace(text.find("SOLVER"), 6, solver);
  text.replace(text.find("FRACTURE"), 8,
               fracture ? std::string(", \"fracture\": ") + c.fracture : std::string());
  return text;
}

std::string unknownBenchCase(const std::string& name, bool withBig) {
  std::string names;
  for (const BenchCase& c : kCases) {
    if (c.big && !withBig) continue;
    if (name == c.name) return {};
    names += (names.empty() ? "'" : ", '") + std::string(c.name) + "'";
  }
  return "--only '" + name + "' is none of the cases: " + names;
}

}  // namespace gf::cli
