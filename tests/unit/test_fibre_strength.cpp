// Anisotropic edge strength (FractureSettings::fibreStrengthRatio): Hankinson's law at edges
// along, across and at 45 deg to the fibres, the per-edge mean over a fibre field against a
// direct recomputation, and the validation of the ratio.
#include <graphfrac/mesh.h>
#include <graphfrac/world.h>
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include "fracture/fracture_model.h"
#include "mesh/edge_graph.h"

namespace gf::detail {
namespace {

constexpr double kAcross = 1e5;
constexpr double kRatio = 4;

FractureSettings settings(double ratio) {
  FractureSettings s;
  s.enabled = true;
  s.strength = kAcross;
  s.fibreStrengthRatio = ratio;
  return s;
}

Vec3 edgeDirection(const TetMesh& m, const EdgeGraph& g, int32_t e) {
  const double* a = &m.positions[3 * size_t(g.edgeNodes[2 * e])];
  const double* b = &m.positions[3 * size_t(g.edgeNodes[2 * e + 1])];
  const Vec3 d{b[0] - a[0], b[1] - a[1], b[2] - a[2]};
  return (1.0 / norm(d)) * d;
}

TEST(FibreStrength, HankinsonLawAlongAcrossAndAt45Degrees) {
  // Closed forms of sigma(theta) = sigma_across r / (r sin^2 + cos^2) at theta = 0, 90, 45 deg.
  EXPECT_DOUBLE_EQ(fibreEdgeStrength(kAcross, kRatio, 1.0), kRatio * kAcross);
  EXPECT_DOUBLE_EQ(fibreEdgeStrength(kAcross, kRatio, 0.0), kAcross);
  EXPECT_DOUBLE_EQ(fibreEdgeStrength(kAcross, kRatio, 0.5), 2 * kRatio / (kRatio + 1) * kAcross);
  EXPECT_DOUBLE_EQ(fibreEdgeStrength(kAcross, 1.0, 0.3), kAcross);  // ratio 1: isotropic

  // One unit cube (6 Kuhn tets) with fibres along x: its axis edges are along or across the
  // fibres, its x-y face diagonal at 45 deg, its x-z and y-z diagonals (cos^2 1/2 and 0) too.
  const TetMesh m = gen::box(1, 1, 1, 1, 1, 1);
  const EdgeGraph g = EdgeGraph::build(m.tets.data(), m.tetCount(), m.nodeCount());
  FibreView fibres;
  fibres.present = true;
  fibres.constant = Vec3{1, 0, 0};
  auto r = FractureModel::build(restView(m), g, settings(kRatio), nullptr, fibres);
  ASSERT_TRUE(r.ok()) << r.error().message;
  const FractureModel& model = r.value();
  int along = 0, across = 0, at45 = 0;
  for (int32_t e = 0; e < g.edgeCount; ++e) {
    const Vec3 d = edgeDirection(m, g, e);
    const double s = model.strength[size_t(e)];
    if (std::fabs(std::fabs(d.x) - 1) < 1e-12) {
      EXPECT_NEAR(s, kRatio * kAcross, 1e-9 * kAcross) << "edge " << e << " along the fibres";
      ++along;
    } else if (std::fabs(d.x) < 1e-12) {
      EXPECT_NEAR(s, kAcross, 1e-9 * kAcross) << "edge " << e << " across the fibres";
      ++across;
    } else if (std::fabs(std::fabs(d.x) - std::sqrt(0.5)) < 1e-12) {
      EXPECT_NEAR(s, 2 * kRatio / (kRatio + 1) * kAcross, 1e-9 * kAcross) << "edge " << e;
      ++at45;
    }
  }
  EXPECT_EQ(along, 4);  // the cube's 4 x edges
  EXPECT_GT(across, 0);
  EXPECT_GT(at45, 0);
}

TEST(FibreStrength, FibreFieldAveragesCosSquaredOverTheEdgesTets) {
  const TetMesh m = gen::box(1, 1, 1, 2, 2, 2);
  const EdgeGraph g = EdgeGraph::build(m.tets.data(), m.tetCount(), m.nodeCount());
  // A different unit direction per tet, so edges inside the box see several.
  std::vector<Vec3> field(m.tetCount());
  for (size_t t = 0; t < field.size(); ++t) {
    const double a = 0.7 * double(t), b = 0.3 * double(t);
    field[t] = Vec3{std::cos(a) * std::cos(b), std::sin(a) * std::cos(b), std::sin(b)};
  }
  FibreView fibres;
  fibres.present = true;
  fibres.perTet = field.data();
  auto r = FractureModel::build(restView(m), g, settings(kRatio), nullptr, fibres);
  ASSERT_TRUE(r.ok()) << r.error().message;
  // Recomputed from the tets' node lists, not from the graph's edge-to-tet map.
  std::vector<double> sum(size_t(g.edgeCount), 0.0);
  std::vector<int> count(size_t(g.edgeCount), 0);
  for (size_t t = 0; t < m.tetCount(); ++t)
    for (int k = 0; k < 6; ++k) {
      const int32_t e = g.tetEdges[6 * t + size_t(k)];
      const double c = dot(edgeDirection(m, g, e), field[t]);
      sum[size_t(e)] += c * c;
      ++count[size_t(e)];
    }
  for (int32_t e = 0; e < g.edgeCount; ++e) {
    const double cos2 = sum[size_t(e)] / count[size_t(e)];
    const double expect = kAcross * kRatio / (kRatio * (1 - cos2) + cos2);
    EXPECT_NEAR(r.value().strength[size_t(e)], expect, 1e-9 * kAcross) << "edge " << e;
  }
}

TEST(FibreStrength, RatioIsValidated) {
  const TetMesh m = gen::box(1, 1, 1, 1, 1, 1);
  const EdgeGraph g = EdgeGraph::build(m.tets.data(), m.tetCount(), m.nodeCount());
  FibreView fibres;
  fibres.present = true;
  for (const double bad : {0.0, -2.0, std::nan(""), std::numeric_limits<double>::infinity()}) {
    auto r = FractureModel::build(restView(m), g, settings(bad), nullptr, fibres);
    ASSERT_FALSE(r.ok()) << bad;
    EXPECT_NE(r.error().message.find("fibreStrengthRatio"), std::string::npos);
  }
  // Without fibres only the isotropic ratio is accepted.
  EXPECT_TRUE(FractureModel::build(restView(m), g, settings(1), nullptr, {}).ok());
  auto r = FractureModel::build(restView(m), g, settings(kRatio), nullptr, {});
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.error().message.find("fibreStrengthRatio"), std::string::npos);
  EXPECT_NE(r.error().message.find("fibreStiffness"), std::string::npos);

  // The same through World: a body without fibre stiffness is refused, naming the field.
  BodyDef def;
  def.mesh = m;
  def.fracture = settings(kRatio);
  World world(WorldDef{});
  auto id = world.createBody(def);
  ASSERT_FALSE(id.ok());
  EXPECT_NE(id.error().message.find("fibreStrengthRatio"), std::string::npos) << id.error().message;
  def.material.fibreStiffness = 1e5;
  EXPECT_TRUE(world.createBody(def).ok());
}

}  // namespace
}  // namespace gf::detail
