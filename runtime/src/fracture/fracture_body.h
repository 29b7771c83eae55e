// Per-body fracture at run time (thesis ch. 4, SPEC §2): the edge graph, the damage state and
// what a step does with them. Design: fracture is detected once per step, at its start, from
// the material-frame stress of x_n (the state the previous step ended in); newly broken edges
// change the element masks and the lagged chi before the implicit solve, so the solve and its
// Hessian see one consistent energy. The sparse pattern never changes: a broken edge only
// changes element values. Bodies without fracture have no FractureBody at all.
#pragma once

#include <memory>
#include <vector>

#include "fem/element_stage.h"
#include "fem/fem_body.h"
#include "fracture/criterion.h"
#include "fracture/cutting.h"
#include "fracture/fracture_model.h"
#include "fracture/impurity.h"
#include "graphfrac/jobs.h"
#include "kernels/math.h"
#include "mesh/edge_graph.h"
#include "surface/fragments.h"

namespace gf::detail {

/// A cut waiting for the next step (World::cut).
struct PendingCut {
  Blade blade;
  BladePose from, to;
};

/// What a run changes of a body's fracture, in one struct: a snapshot is a copy of it and a
/// device mirror copies its buffers. Everything else of a FractureBody is fixed at creation
/// (the model, the graph, the edge matrices) or scratch.
struct FractureData {
  std::vector<uint8_t> broken;   ///< Per edge: 1 = broken; never reset (damage does not heal).
  std::vector<uint8_t> tetMask;  ///< Per tet: bit k set when local edge k is broken.
  std::vector<double> chi;       ///< Per tet: the lagged degradation factor (eq 4.33).
  /// Per edge sigma_th now: the model's, scaled by impurities or set by setEdgeStrengths.
  std::vector<double> strength;
  std::vector<EdgeBreak> breaks;      ///< Broken by the last detect(), sorted by edge id.
  std::vector<uint8_t> breakCause;    ///< FractureEvent::Cause of each of `breaks`.
  std::vector<FragmentSplit> splits;  ///< Fragments created by the last detect().
  FragmentProperties props;           ///< of the fragments when they were created
  Fragments fragments;
  std::vector<PendingCut> pendingCuts;
  std::vector<int32_t> breakOrder;  ///< Every broken edge in the order it broke.
  /// Per edge with SplitPoint::ForceRatio (empty otherwise): where the render surface splits
  /// it, as the parameter from edgeNodes[2e]; 0.5 until it breaks, then set once.
  std::vector<double> splitRatio;
  int32_t brokenCount = 0;
  /// Per fragment, 1 for a chip (FractureStats::chips); recomputed on steps where edges break.
  std::vector<uint8_t> chip;
  int32_t chips = 0;          ///< The count of ones in chip.
  bool brittleFired = false;  ///< Brittle crack planes start once per body.
  bool hasImpurity = false;
  ImpurityField impurity;  ///< Meaningful only with hasImpurity.
};

class FractureBody;

/// The element pass of a body at x (damage from `fracture`, none when null), outputs unset:
/// the one place that binds FemModel, FemState and the damage to an ElementStage.
ElementStage bodyElementStage(const FemModel& fem, const FemState& data,
                              const FractureBody* fracture, const double* x);

/// Where the criterion runs elsewhere (the body's device on the CUDA backend), for
/// FractureBody::detect: the stresses and the candidate edges there, only those back.
class CriterionDevice {
 public:
  virtual ~CriterionDevice() = default;
  /// The stresses of `stage` (its flags; the body's arrays it names, at its x), kept there.
  virtual bool stresses(const CriterionStressStage& stage) = 0;
  /// findCandidateEdges on them against `host`'s arrays, the candidates into host's (as
  /// gpu::DeviceCriterion::find); -1 when it failed.
  virtual int32_t candidates(const CriterionView& host, double weakest) = 0;
  /// The kept stresses into `stress` on the host, 6 per tet.
  virtual bool readStresses(double* stress) = 0;
};

class FractureBody {
 public:
  /// Builds the graph, the fracture model and the per-tet edge matrices. Errors name the
  /// field (e.g. a strength that is not positive).
  static Result<std::unique_ptr<FractureBody>> create(const FemModel& fem, const FemState& data,
                                                      JobSystem& jobs);

  /// Start of a step: pending cuts, then the stress criterion (and brittle planes) on the
  /// positions x (fragments created get their velocities from data.v). stressBuffer() must hold the
  /// material-frame stress of every undamaged tet at x (the integrator's first element pass writes
  /// it); damaged tets are evaluated here. Fills breaks() and splits(); returns the number of edges
  /// broken. With stressesReady false, the stresses of undamaged tets are computed here too.
  /// svdCache (kSvdCacheStride per tet, or null): the integrator's SVD cache, read for the tets
  /// whose F the last element pass saw and written for the others (svd3.h). `device`: the
  /// stresses (with stressesReady, the element pass left those of the undamaged tets there,
  /// not in stressBuffer()) and the candidates computed there; where it fails, here.
  int32_t detect(const FemModel& fem, const FemState& data, const double* x, JobSystem& jobs,
                 bool stressesReady = true, double* svdCache = nullptr,
                 CriterionDevice* device = nullptr);
  /// 6 per tet (Voigt), written by the element pass.
  double* stressBuffer() { return m_stress.data(); }

  /// Kernel inputs of the element pass.
  int damageModel() const { return m_damageModel; }
  const uint8_t* tetMask() const { return m_data.tetMask.data(); }
  const double* chi() const { return m_data.chi.data(); }
  /// Per-tet edge matrices T and T^-1 of the projection model (e_d = T e, eq 4.25); null for the
  /// degradation model, which does not use them.
  const Mat<6, 6>* edgeMatrices() const { return m_T.empty() ? nullptr : m_T.data(); }
  const Mat<6, 6>* edgeMatrixInverses() const { return m_Tinv.empty() ? nullptr : m_Tinv.data(); }

  void queueCut(PendingCut cut) { m_data.pendingCuts.push_back(std::move(cut)); }

  const EdgeGraph& graph() const { return m_graph; }
  const std::vector<uint8_t>& broken() const { return m_data.broken; }
  const Fragments& fragments() const { return m_data.fragments; }
  /// Edges broken by the last detect(), sorted by edge id, with what broke them.
  const std::vector<EdgeBreak>& breaks() const { return m_data.breaks; }
  const std::vector<uint8_t>& breakCause() const { return m_data.breakCause; }
  /// Fragments created by the last detect() and their properties at that moment.
  const std::vector<FragmentSplit>& splits() const { return m_data.splits; }
  const FragmentProperties& splitProperties() const { return m_data.props; }
  int32_t brokenCount() const { return m_data.brokenCount; }
  /// Fragments that hold no whole (unsplit) tet (FractureStats::chips).
  int32_t chipCount() const { return m_data.chips; }
  /// Per fragment, 1 for a chip.
  const std::vector<uint8_t>& chipFlags() const { return m_data.chip; }
  /// Every broken edge in the order it broke (the first k are the broken set after k breaks).
  const std::vector<int32_t>& breakOrder() const { return m_data.breakOrder; }

  /// Current per-edge strengths sigma_th; World validates replacements.
  const std::vector<double>& strengths() const { return m_data.strength; }
  /// With impurities the given strengths become the base the impurities scale.
  void setStrengths(std::vector<double> strength);

  /// The body's impurities (thesis sec 5.2), or null when it has none.
  const ImpurityField* impurities() const {
    return m_data.hasImpurity ? &m_data.impurity : nullptr;
  }
  /// Applies an impurity map (checked with ImpurityMap::check) to the rest mesh; an error
  /// naming the field (a polyline point off the surface) changes nothing. A body without
  /// impurities gets a field of pure nodes first.
  Result<void> applyImpurityMap(const FemModel& fem, const ImpurityMap& map);

  /// Per-edge split ratios for CrackSurface::setSplitRatios, or null for midpoints
  /// (FractureSettings::splitPoint).
  const double* splitRatios() const {
    return m_data.splitRatio.empty() ? nullptr : m_data.splitRatio.data();
  }
  /// The element pass of this body at x with its damage as it is now (outputs unset).
  ElementStage elementStage(const FemModel& fem, const FemState& data, const double* x) const;

  /// Everything a run changes (World::snapshot copies it, restore puts it back).
  const FractureData& data() const { return m_data; }
  void restore(const FractureData& data) { m_data = data; }

 private:
  // Completes m_stress at x: damaged tets (scaled or zero), and undamaged ones when asked.
  void computeStresses(const FemModel& fem, const FemState& data, const double* x,
                       bool undamagedToo, double* svdCache, JobSystem& jobs);
  // The stage that does it, writing into m_stress.
  CriterionStressStage stressStage(const FemModel& fem, const FemState& data, const double* x,
                                   bool undamagedToo, double* svdCache = nullptr);
  // The split points of m_data.breaks[first..] (SplitPoint::ForceRatio), before they apply.
  void computeSplits(size_t first, const FemModel& fem, const FemState& data, const double* x,
                     JobSystem& jobs);
  // Degradation model: breaks (cause Severed, appended) the unbroken edges around the
  // breaks m_data.breaks[first..] of a batch (the criterion's; with
  // FractureSettings::releaseEveryBatch also a cut, the pre-cuts, the brittle planes') whose
  // every tet is now split. A split tet has chi = 0 and zero criterion
  // stress, so no load could ever break such an edge, yet it would keep the graph's pieces one
  // fragment (docs/design.md "Severed edges").
  // With keepSlices (blade and pre-cut batches), an edge between two chips that no unbroken
  // edge joins to a piece stays: the blades cut out a slice thinner than a cell, which stays
  // one fragment (a chip of several nodes) rather than falling apart into loose nodes.
  void releaseSevered(size_t first, const double* x, bool keepSlices);
  // Split points, then applyBreaks, for m_data.breaks[first..], each cause kept with its break.
  void finishBatch(size_t first, const FemModel& fem, const FemState& data, const double* x,
                   JobSystem& jobs);
  // Marks the fragments that hold no whole tet, from the broken flags and fragments as they are.
  void findChips(JobSystem& jobs);
  // Masks, chi and fragments after edges in m_data.breaks[first..] broke.
  void applyBreaks(size_t first, const FemModel& fem, const FemState& data, const double* x,
                   JobSystem& jobs);

  // Fixed at creation.
  EdgeGraph m_graph;
  FractureModel m_model;
  int m_damageModel = 1;
  std::vector<Vec3> m_restDir;         // 6 per tet, unit rest edge directions
  std::vector<Mat<6, 6>> m_T, m_Tinv;  // projection model only
  std::vector<double> m_nodeVolume;
  // SplitPoint::ForceRatio only: node -> 4 tet + corner (CSR, element order), as the
  // integrator's gather, for the nodal forces of breaking edges.
  std::vector<int32_t> m_nodeRefStart, m_nodeRef;
  FractureData m_data;
  // Scratch: rewritten before every read.
  std::vector<double> m_stress;
  std::vector<int32_t> m_newEdges;
  FragmentScratch m_fragmentScratch;
  std::vector<uint8_t> m_releaseMark;  // per edge, within releaseSevered: already listed
  CriterionWorkspace m_ws;
  CutWorkspace m_cutWs;
};

}  // namespace gf::detail
