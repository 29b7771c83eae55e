// `graphfrac bench haptic`: the cost of one haptic sample (HapticContact, thesis sec 7.2.3) on
// render surfaces of growing size. A 10 x 5 x 10 cm block of N x N/2 x N cells, its bottom
// lifted at 1 cm/s by a grip, steps at 62.5 Hz while a 2 cm cube is lowered into its top at
// 1 cm/s and sampled at 1 kHz (16 samples per step, the new surface blended in over a step).
// Per sample: median, 99th percentile and worst microseconds, the contacts at the end, and the
// microseconds of handing the surface over (setSurface, once per step); continuous and discrete.
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <vector>

#include "cli/bench_args.h"
#include "cli/commands.h"
#include "graphfrac/sculpt.h"
#include "graphfrac/world.h"

namespace gf::cli {

namespace {

double usSince(std::chrono::steady_clock::time_point t) {
  return std::chrono::duration<double, std::micro>(std::chrono::steady_clock::now() - t).count();
}

double quantile(std::vector<double> v, double q) {
  std::sort(v.begin(), v.end());
  return v[std::min(v.size() - 1, size_t(q * double(v.size())))];
}

}  // namespace

int benchHaptic(int argc, char** argv) {
  int cells = 0, steps = 40;  // cells 0: 6, 12 and 24
  if (const int e = parseBenchArgs(
          "haptic", argc, argv,
          {{"--cells", &cells, 2, kBenchMaxCells}, {"--steps", &steps, 1, kBenchMaxCount}});
      e != kExitOk)
    return e;
  const std::vector<int> sizes = cells > 0 ? std::vector<int>{cells} : std::vector<int>{6, 12, 24};
  std::printf("# %d world steps of 16 ms, 16 haptic samples of 1 ms each\n", steps);
  std::printf(
      "cells,surface_triangles,mode,sample_us_median,sample_us_p99,sample_us_max,contacts_end,"
      "set_surface_us_median,force_end_N\n");
  for (int cells : sizes) {
    for (bool continuous : {true, false}) {
      World world(WorldDef{});
      BodyDef def;
      def.mesh = gen::box(0.1, 0.05, 0.1, cells, std::max(1, cells / 2), cells);
      def.material = Material::stableNeoHookean(2e4, 0.3, 1000);
      def.grips.push_back({});
      for (size_t n = 0; n < def.mesh.nodeCount(); ++n)
        if (def.mesh.positions[3 * n + 1] < 1e-9) def.grips[0].nodes.push_back(int32_t(n));
      const Result<BodyId> id = world.createBody(def);
      if (!id.ok()) {
        std::fprintf(stderr, "graphfrac bench haptic: %s\n", id.error().message.c_str());
        return kExitScene;
      }
      (void)world.setGripVelocity(id.value(), 0, {0, 0.01f, 0});
      // A 2 cm cube 1 mm above the top, off the block's centre lines.
      std::vector<glm::dvec3> cube;
      for (int i = 0; i < 8; ++i)
        cube.push_back(glm::dvec3(0.043, 0.061, 0.057) +
                       0.01 * glm::dvec3(i & 1 ? 1 : -1, i & 2 ? 1 : -1, i & 4 ? 1 : -1));
      std::vector<uint32_t> tri;
      const int quads[6][4] = {{0, 2, 3, 1}, {4, 5, 7, 6}, {0, 1, 5, 4},
                               {2, 6, 7, 3}, {0, 4, 6, 2}, {1, 3, 7, 5}};
      for (const auto& f : quads)
        for (int t : {0, 1})
          for (int c : {0, t + 1, t + 2}) tri.push_back(uint32_t(f[c]));
      HapticContactSettings settings;
      settings.stiffness = 500;
      settings.continuous = continuous;
      HapticContact h = HapticContact::create(cube, tri, settings).value();
      const SurfaceView first = world.surface(id.value());
      const size_t triangles = first.indices.size() / 3;
      (void)h.setSurface(first, 0.016);
      std::vector<double> sampleUs, surfaceUs;
      glm::dvec3 force(0.0);
      int sample = 0;
      for (int step = 0; step < steps; ++step) {
        for (int i = 0; i < 16; ++i) {
          ++sample;
          std::vector<glm::dvec3> at = cube;
          for (glm::dvec3& p : at) p.y -= 1e-5 * sample;
          const auto t0 = std::chrono::steady_clock::now();
          force = h.sample(at, 1e-3).value();
          sampleUs.push_back(usSince(t0));
        }
        (void)world.step(0.016);
        const SurfaceView s = world.surface(id.value());
        const auto t0 = std::chrono::steady_clock::now();
        (void)h.setSurface(s, 0.016);
        surfaceUs.push_back(usSince(t0));
      }
      std::printf("%d,%zu,%s,%.1f,%.1f,%.1f,%d,%.1f,%.4g\n", cells, triangles,
                  continuous ? "continuous" : "discrete", quantile(sampleUs, 0.5),
                  quantile(sampleUs, 0.99), quantile(sampleUs, 1.0), h.contactCount(),
                  quantile(surfaceUs, 0.5), force.y);
      std::fflush(stdout);
    }
  }
  return kExitOk;
}

}  // namespace gf::cli
