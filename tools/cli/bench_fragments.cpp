// `graphfrac bench fragments`: the cost of keeping a body's fragments on a break step
// (Fragments::update, then Fragments::compute when the partition changed), replaying recorded
// break sequences on a unit cube of N^3 cells: a random shatter (random edges in batches until
// 60 % are broken) and a crack plane (the edges crossing x = 0.5, swept along y so the body
// parts on the last of 40 steps). Prints ms per break step, best of R rounds, and a checksum of
// the final partition so that two binaries can be compared for identical results.
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <numeric>
#include <random>
#include <vector>

#include "cli/bench_args.h"
#include "cli/commands.h"
#include "graphfrac/jobs.h"
#include "graphfrac/mesh.h"
#include "mesh/edge_graph.h"
#include "step/executor.h"
#include "surface/fragments.h"

namespace gf::cli {

namespace {

using detail::EdgeGraph;
using detail::Fragments;

struct Sequence {
  const char* name;
  std::vector<std::vector<int32_t>> batches;
};

struct Timing {
  double updateMs = 1e300, totalMs = 1e300;
  int32_t fragments = 0, splitSteps = 0;
  uint64_t checksum = 0;
};

Timing replay(const EdgeGraph& g, const Sequence& seq, const std::vector<double>& volume,
              const std::vector<double>& x, JobSystem& jobs) {
  std::vector<double> partials;
  const detail::CpuExecutor exec(jobs, &partials);
  std::vector<uint8_t> broken(size_t(g.edgeCount), 0);
  detail::FragmentScratch scratch;
  detail::FragmentProperties props;
  Fragments fr;
  fr.build(exec, g, broken.data(), scratch);
  fr.compute(exec, volume, volume, x.data(), x.data(), props, scratch);
  Timing t;
  double update = 0, total = 0;
  for (const std::vector<int32_t>& batch : seq.batches) {
    for (int32_t e : batch) broken[size_t(e)] = 1;
    const auto t0 = std::chrono::steady_clock::now();
    const bool split = fr.update(exec, g, broken.data(), batch, scratch);
    const auto t1 = std::chrono::steady_clock::now();
    if (split) fr.compute(exec, volume, volume, x.data(), x.data(), props, scratch);
    const auto t2 = std::chrono::steady_clock::now();
    update += std::chrono::duration<double, std::milli>(t1 - t0).count();
    total += std::chrono::duration<double, std::milli>(t2 - t0).count();
    t.splitSteps += split ? 1 : 0;
  }
  const double steps = double(std::max<size_t>(1, seq.batches.size()));
  t.updateMs = update / steps;
  t.totalMs = total / steps;
  t.fragments = fr.count();
  uint64_t h = 1469598103934665603ull;
  for (int32_t f : fr.nodeFragment()) h = (h ^ uint64_t(uint32_t(f))) * 1099511628211ull;
  t.checksum = h;
  return t;
}

}  // namespace

int benchFragments(int argc, char** argv) {
  int rounds = 5, threads = 1, cells = 0;  // cells 0: 16 and 32
  if (const int e = parseBenchArgs("fragments", argc, argv,
                                   {{"--cells", &cells, 2, kBenchMaxCells},
                                    {"--rounds", &rounds, 1, kBenchMaxCount},
                                    {"--threads", &threads, 1, kBenchMaxThreads}});
      e != kExitOk)
    return e;
  const std::vector<int> cellCounts =
      cells > 0 ? std::vector<int>{cells} : std::vector<int>{16, 32};
  ThreadPoolJobSystem pool(threads);
  JobSystem& jobs = threads > 1 ? static_cast<JobSystem&>(pool) : serialJobs();
  std::printf(
      "# fragments: ms per break step (update / update + compute), best of %d, %d thread%s\n",
      rounds, threads, threads > 1 ? "s" : "");
  std::printf("%-8s %-14s %6s %6s %10s %10s %6s %18s\n", "tets", "sequence", "steps", "splits",
              "update", "total", "frags", "checksum");
  for (int cells : cellCounts) {
    const TetMesh mesh = gen::box(1.0, 1.0, 1.0, cells, cells, cells);
    const EdgeGraph g = EdgeGraph::build(mesh.tets.data(), mesh.tetCount(), mesh.nodeCount());
    const std::vector<double> volume = Fragments::nodeVolumes(
        mesh.tets.data(), mesh.tetCount(), mesh.positions.data(), mesh.nodeCount());
    Sequence sequences[2] = {{"random shatter", {}}, {"crack plane", {}}};
    {
      std::vector<int32_t> order(size_t(g.edgeCount));
      std::iota(order.begin(), order.end(), 0);
      std::mt19937 rng(12345);
      std::shuffle(order.begin(), order.end(), rng);
      const size_t perStep = std::max<size_t>(1, order.size() / 100);
      for (size_t b = 0; b + perStep <= order.size() * 6 / 10; b += perStep)
        sequences[0].batches.emplace_back(order.begin() + long(b),
                                          order.begin() + long(b + perStep));
    }
    {
      std::vector<std::pair<double, int32_t>> crossing;
      for (int32_t e = 0; e < g.edgeCount; ++e) {
        const double* p = &mesh.positions[3 * size_t(g.edgeNodes[2 * size_t(e)])];
        const double* q = &mesh.positions[3 * size_t(g.edgeNodes[2 * size_t(e) + 1])];
        if ((p[0] < 0.5) != (q[0] < 0.5)) crossing.emplace_back(p[1] + q[1], e);
      }
      std::sort(crossing.begin(), crossing.end());
      const size_t steps = 40;
      for (size_t s = 0; s < steps; ++s) {
        std::vector<int32_t> batch;
        for (size_t k = s * crossing.size() / steps; k < (s + 1) * crossing.size() / steps; ++k)
          batch.push_back(crossing[k].second);
        sequences[1].batches.push_back(std::move(batch));
      }
    }
    for (const Sequence& seq : sequences) {
      Timing best;
      for (int r = 0; r < rounds; ++r) {
        const Timing t = replay(g, seq, volume, mesh.positions, jobs);
        best.updateMs = std::min(best.updateMs, t.updateMs);
        best.totalMs = std::min(best.totalMs, t.totalMs);
        best.fragments = t.fragments;
        best.splitSteps = t.splitSteps;
        best.checksum = t.checksum;
      }
      std::printf("%-8zu %-14s %6zu %6d %10.4f %10.4f %6d %18llx\n", mesh.tetCount(), seq.name,
                  seq.batches.size(), best.splitSteps, best.updateMs, best.totalMs, best.fragments,
                  static_cast<unsigned long long>(best.checksum));
    }
  }
  return kExitOk;
}

}  // namespace gf::cli
