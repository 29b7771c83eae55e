// A self contact pair re-linearised at the Newton iterate (HalfSpaceContacts::pair, the
// SelfPair*Stages of fem/node_stage.h), checked against truths worked out here: the energy is
// k d^2 / 2 of the vertex's signed distance from the face's plane as the face now is (a
// determinant over the face's area, not the kernel's barycentric frame), its gradient matches
// central finite differences of that energy, and the Newton matrix the body's step assembles
// (diagonal blocks plus the matrix-free cross blocks) is the Gauss-Newton k g g^T of that
// gradient, PSD. The configurations turn the face by 0.1-0.3 rad and slide the vertex up to
// beyond the face's edge after the pair was found, as a piece landing on a turning corner does
// (docs/validation.md, "Self pairs solved inside the body's Newton step"): a pair that kept the
// normal and nearest point of the face's prediction fails all three.
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <array>
#include <cmath>
#include <vector>

#include "fem/node_stage.h"
#include "kernels/contact.h"

namespace gf {
namespace {

constexpr double kStiffness = 3.0e3;  // N/m, a landing piece's vertex (docs/validation.md)

Vec3 rotated(Vec3 p, Vec3 axis, double angle) {
  // Rodrigues' formula about a unit axis.
  const double c = std::cos(angle), s = std::sin(angle);
  return c * p + s * cross(axis, p) + ((1 - c) * dot(axis, p)) * axis;
}

// One vertex (node 0) paired with one face (nodes 1-3), found when the face lay in z = 0 with
// its outward normal +z and the vertex over the point w of it.
struct OnePair {
  std::array<int32_t, 5> start{0, 1, 1, 1, 1};
  Vec3 point{0, 0, 0}, normal{0, 0, 1}, weight{0.5, 0.25, 0.25};
  double stiffness = kStiffness;
  std::array<int32_t, 3> faceNode{1, 2, 3};
  int32_t owner = 0;
  std::array<int32_t, 5> reactionStart{0, 0, 1, 2, 3};
  std::array<int32_t, 3> reaction{0, 1, 2};
  std::array<uint8_t, 4> fixed{0, 0, 0, 0};
  double skin = 0;
  // Friction: its lagged normal force times mu, the smoothing length, and the step's start
  // (null: the face's predicted motion, none here, is what the vertex slides against).
  double muLambda = 0, slipEps = 0;
  Vec3 faceMotion{0, 0, 0};
  const double* xn = nullptr;

  HalfSpaceContacts at(const double* x) const {
    HalfSpaceContacts h;
    h.start = start.data();
    h.point = &point;
    h.normal = &normal;
    h.stiffness = &stiffness;
    h.faceNode = faceNode.data();
    h.weight = &weight;
    h.owner = &owner;
    h.reactionStart = reactionStart.data();
    h.reaction = reaction.data();
    h.selfSkin = skin;
    if (muLambda > 0) {
      h.muLambda = &muLambda;
      h.faceMotion = &faceMotion;
      h.slipEps = slipEps;
      h.Xn = xn;
    }
    return h.at(x);
  }
  // The energy at x and its gradient (the vertex's penalty and the face nodes' reactions).
  double energy(const std::vector<double>& x, std::vector<double>* grad = nullptr,
                std::array<Mat3, 4>* blocks = nullptr) const {
    return withReactions(x, grad, blocks, [](const HalfSpaceContacts& h, Vec3& g, Mat3& b) {
      return h.contact(0, h.nodeAt(0), g, b);
    });
  }
  // The friction at x (the vertex in front of the plane, so no penalty acts), its gradient
  // (the vertex's friction and the face nodes' reactions) and the diagonal blocks.
  double frictionEnergy(const std::vector<double>& x, std::vector<double>* grad = nullptr,
                        std::array<Mat3, 4>* blocks = nullptr) const {
    const Vec3 xv0{xn[0], xn[1], xn[2]};
    return withReactions(x, grad, blocks, [&](const HalfSpaceContacts& h, Vec3& g, Mat3& b) {
      EXPECT_LT(h.depth(0, h.nodeAt(0)), 0.0);
      return h.friction(0, h.nodeAt(0), xv0, g, b);
    });
  }
  // The vertex's term at x, the face nodes' reactions, their gradient and diagonal blocks.
  template <class VertexTerm>
  double withReactions(const std::vector<double>& x, std::vector<double>* grad,
                       std::array<Mat3, 4>* blocks, VertexTerm vertex) const {
    const HalfSpaceContacts h = at(x.data());
    std::array<Vec3, 4> g{};
    std::array<Mat3, 4> b{};
    const double e = vertex(h, g[0], b[0]);
    for (int32_t n = 1; n < 4; ++n) h.reactionTerms(n, g[size_t(n)], b[size_t(n)]);
    if (grad)
      for (int n = 0; n < 4; ++n)
        for (int c = 0; c < 3; ++c) (*grad)[size_t(3 * n + c)] = g[size_t(n)][c];
    if (blocks) *blocks = b;
    return e;
  }
};

// The Newton matrix the body's step solves with for the pair at x: the diagonal blocks (from
// OnePair::energy or frictionEnergy) plus the stages' matrix-free cross terms, column by column;
// active and friction are SelfPairActiveStage's.
Eigen::Matrix<double, 12, 12> newtonMatrix(const OnePair& pair, const std::vector<double>& x,
                                           const std::array<Mat3, 4>& blocks, double* active,
                                           double* friction) {
  const HalfSpaceContacts h = pair.at(x.data());
  double s = 0;
  Vec3 n, w, t;
  const detail::SelfPairActiveStage activeStage{h, 1.0, active, &n, &w, friction};
  activeStage(0);
  Eigen::Matrix<double, 12, 12> H;
  for (int j = 0; j < 12; ++j) {
    std::vector<double> p(12, 0.0), y(12, 0.0);
    p[size_t(j)] = 1;
    for (int r = 0; r < 3; ++r) y[size_t(3 * (j / 3) + r)] = blocks[size_t(j / 3)](r, j % 3);
    const detail::SelfPairProjectStage project{h,        pair.fixed.data(), active, &n, &w,
                                               friction, p.data(),          &s,     &t};
    project(0);
    const detail::SelfPairCouplingStage coupling{
        h, pair.fixed.data(), active, &n, &w, friction, &s, &t, p.data(), y.data()};
    for (int32_t node = 0; node < 4; ++node) coupling(node);
    for (int i = 0; i < 12; ++i) H(i, j) = y[size_t(i)];
  }
  return H;
}

// The vertex's signed depth behind the plane of face (x1, x2, x3): six times the tetrahedron's
// signed volume over twice the face's area.
double trueDepth(const std::vector<double>& x) {
  Eigen::Matrix3d m;
  Eigen::Vector3d v(x[0], x[1], x[2]), p[3];
  for (int i = 0; i < 3; ++i)
    p[i] = Eigen::Vector3d(x[size_t(3 + 3 * i)], x[size_t(4 + 3 * i)], x[size_t(5 + 3 * i)]);
  m << (p[0] - v).transpose(), (p[1] - v).transpose(), (p[2] - v).transpose();
  return m.determinant() / (p[1] - p[0]).cross(p[2] - p[0]).norm();
}

// The face, 4 cm, turned by angle about an axis through its corner and moved; the vertex at
// face coordinates (u, v), depth behind its current plane.
std::vector<double> configuration(double angle, double u, double v, double depth) {
  const double L = 0.04;
  const Vec3 axis = (1.0 / std::sqrt(1.0 + 0.16 + 0.09)) * Vec3{1.0, 0.4, -0.3};
  const Vec3 shift{0.003, -0.002, -0.004};
  const Vec3 face[3] = {{0, 0, 0}, {L, 0, 0}, {0, L, 0}};
  std::vector<double> x(12);
  Vec3 q[3];
  for (int i = 0; i < 3; ++i) q[i] = rotated(face[i], axis, angle) + shift;
  const Vec3 n = (1.0 / norm(cross(q[1] - q[0], q[2] - q[0]))) * cross(q[1] - q[0], q[2] - q[0]);
  const Vec3 xv = q[0] + u * (q[1] - q[0]) + v * (q[2] - q[0]) - depth * n;
  for (int c = 0; c < 3; ++c) x[size_t(c)] = xv[c];
  for (int i = 0; i < 3; ++i)
    for (int c = 0; c < 3; ++c) x[size_t(3 + 3 * i + c)] = q[i][c];
  return x;
}

struct Case {
  double angle, u, v, depth;
};
// Over the face, slid near its edge, and past the edge (its projection outside the triangle).
const Case kCases[] = {{0.1, 0.3, 0.3, 1e-3},
                       {0.1, 0.7, 0.25, 2e-3},
                       {0.2, 0.9, 0.4, 1.5e-3},
                       {0.3, -0.2, 0.5, 1e-3},
                       {0.1, 1.3, 0.1, 4e-3}};

TEST(SelfPair, EnergyIsThePenaltyOfTheDepthBehindTheFaceAsItNowIs) {
  const OnePair pair;
  for (const Case& c : kCases) {
    const std::vector<double> x = configuration(c.angle, c.u, c.v, c.depth);
    const double d = trueDepth(x);
    ASSERT_NEAR(d, c.depth, 1e-12);
    EXPECT_NEAR(pair.energy(x), 0.5 * kStiffness * d * d, 1e-9 * kStiffness * d * d)
        << "angle " << c.angle << ", at (" << c.u << ", " << c.v << ")";
  }
  // In front of the plane: no energy.
  EXPECT_EQ(pair.energy(configuration(0.1, 0.3, 0.3, -1e-3)), 0.0);
  // The plane a skin in front of the face.
  OnePair skinned;
  skinned.skin = 5e-4;
  const double d = trueDepth(configuration(0.2, 0.6, 0.3, -2e-4)) + skinned.skin;
  EXPECT_NEAR(skinned.energy(configuration(0.2, 0.6, 0.3, -2e-4)), 0.5 * kStiffness * d * d,
              1e-9 * kStiffness * d * d);
}

TEST(SelfPair, GradientMatchesFiniteDifferencesOfTheTrueEnergy) {
  const OnePair pair;
  for (const Case& c : kCases) {
    const std::vector<double> x = configuration(c.angle, c.u, c.v, c.depth);
    std::vector<double> grad(12);
    pair.energy(x, &grad);
    const double h = 1e-7, scale = kStiffness * c.depth;
    for (size_t i = 0; i < 12; ++i) {
      std::vector<double> xp = x, xm = x;
      xp[i] += h;
      xm[i] -= h;
      const double dp = trueDepth(xp), dm = trueDepth(xm);
      const double fd = 0.5 * kStiffness * (dp * dp - dm * dm) / (2 * h);
      EXPECT_NEAR(grad[i], fd, 1e-6 * scale)
          << "angle " << c.angle << ", at (" << c.u << ", " << c.v << "), coordinate " << i;
      // The kernel's own energy, which the line search sees, has the same gradient.
      const double fdOwn = (pair.energy(xp) - pair.energy(xm)) / (2 * h);
      EXPECT_NEAR(grad[i], fdOwn, 1e-6 * scale) << "coordinate " << i;
    }
  }
}

TEST(SelfPair, NewtonMatrixIsTheGaussNewtonOfTheGradientAndPsd) {
  const OnePair pair;
  for (const Case& c : kCases) {
    const std::vector<double> x = configuration(c.angle, c.u, c.v, c.depth);
    std::vector<double> grad(12);
    std::array<Mat3, 4> blocks;
    pair.energy(x, &grad, &blocks);
    double active = 0, friction = 0;
    const Eigen::Matrix<double, 12, 12> H = newtonMatrix(pair, x, blocks, &active, &friction);
    ASSERT_EQ(active, kStiffness);
    // grad = k d g, so k g g^T = grad grad^T / (k d^2).
    const double d = trueDepth(x);
    Eigen::Matrix<double, 12, 1> g;
    for (int i = 0; i < 12; ++i) g(i) = grad[size_t(i)];
    const Eigen::Matrix<double, 12, 12> gaussNewton = g * g.transpose() / (kStiffness * d * d);
    EXPECT_LT((H - gaussNewton).norm(), 1e-9 * gaussNewton.norm())
        << "angle " << c.angle << ", at (" << c.u << ", " << c.v << ")";
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix<double, 12, 12>> eig(H);
    EXPECT_GT(eig.eigenvalues().minCoeff(), -1e-9 * eig.eigenvalues().maxCoeff());
    EXPECT_LT((H - H.transpose()).norm(), 1e-12 * H.norm());
  }
}

// Friction between two pieces of one body (HalfSpaceContacts::slide with x_n known): the vertex
// slides against the face point with the pair's held weights w, moved with the face nodes'
// unknowns, in the plane of the held normal. Truth worked out here: u = P (dx_v - sum_i w_i
// dx_i), P = I - n n^T, energy mu lambda f0(|u|) with IPC's f0 (Li et al. 2020, sec 5), its
// gradient by central differences, and the Newton matrix c c^T (x) mu lambda f1(y) / y P with
// c = (1, -w_1, -w_2, -w_3) (IPC's, without the curvature along u). With the face's predicted
// motion in its place, the friction acted on the vertex alone against a lagged target, and
// pieces of one body resting on each other crept apart (docs/validation.md, "Friction between
// the pieces of one body").
double ipcF0(double y, double eps) {
  return y < eps ? y * y / eps - y * y * y / (3 * eps * eps) + eps / 3 : y;
}
double ipcF1OverY(double y, double eps) { return y < eps ? 2 / eps - y / (eps * eps) : 1 / y; }

struct FrictionCase {
  double angle;  // the face's turn over the step [rad]
  Vec3 slide;    // the vertex's motion beyond the face's [m]
  Vec3 common;   // a motion of all four nodes [m]
};
const FrictionCase kFrictionCases[] = {
    {0.0, {2e-5, -1e-5, 0}, {0, 0, 0}},                // stuck: below the smoothing length
    {0.05, {3e-3, 1e-3, 2e-4}, {0, 0, 0}},             // sliding, the face turning
    {0.2, {-1e-3, 4e-3, 1e-3}, {0.01, -0.02, 0.005}},  // sliding, turning, carried along
    {0.0, {5e-5, 6e-5, 1e-5}, {-0.03, 0.01, 0.02}},    // near the smoothing length, carried
};

TEST(SelfPair, FrictionSlidesAgainstTheFaceItsOwnBodyMoves) {
  OnePair pair;
  pair.muLambda = 0.6 * 4.0;  // mu times a lagged normal force [N]
  pair.slipEps = 1e-4;
  const std::vector<double> start = configuration(0.0, 0.3, 0.3, -1e-3);
  pair.xn = start.data();
  for (const FrictionCase& c : kFrictionCases) {
    // The face turned about an axis through its first corner and carried by `common`, the
    // vertex over the face's point (0.3, 0.3), then moved by `slide`.
    std::vector<double> x = configuration(c.angle, 0.3, 0.3, -1e-3);
    for (int i = 0; i < 12; ++i) x[size_t(i)] += c.common[i % 3];
    for (int k = 0; k < 3; ++k) x[size_t(k)] += c.slide[k];
    auto truth = [&](const std::vector<double>& y) {
      Eigen::Vector3d u(0, 0, 0);
      for (int k = 0; k < 3; ++k) u(k) = y[size_t(k)] - start[size_t(k)];
      for (int i = 0; i < 3; ++i)
        for (int k = 0; k < 3; ++k)
          u(k) -= pair.weight[i] * (y[size_t(3 + 3 * i + k)] - start[size_t(3 + 3 * i + k)]);
      const Eigen::Vector3d n(pair.normal.x, pair.normal.y, pair.normal.z);
      u -= u.dot(n) * n;
      return u;
    };
    const Eigen::Vector3d u = truth(x);
    const double y = u.norm();
    std::vector<double> grad(12);
    std::array<Mat3, 4> blocks;
    const double e = pair.frictionEnergy(x, &grad, &blocks);
    EXPECT_NEAR(e, pair.muLambda * ipcF0(y, pair.slipEps), 1e-12 * pair.muLambda * pair.slipEps);
    // Gradient: central differences of the true energy.
    const double h = 1e-9, scale = pair.muLambda;
    Eigen::Vector3d sum(0, 0, 0);
    for (size_t i = 0; i < 12; ++i) {
      std::vector<double> xp = x, xm = x;
      xp[i] += h;
      xm[i] -= h;
      const double fd =
          pair.muLambda *
          (ipcF0(truth(xp).norm(), pair.slipEps) - ipcF0(truth(xm).norm(), pair.slipEps)) / (2 * h);
      EXPECT_NEAR(grad[i], fd, 1e-5 * scale) << "slide " << y << " m, coordinate " << i;
      sum(long(i % 3)) += grad[i];
    }
    // Action and reaction: the pair gives the body no net force.
    EXPECT_LT(sum.norm(), 1e-12 * scale);
    // The Newton matrix: diagonal blocks plus the matrix-free cross terms.
    double active = 0, friction = 0;
    const Eigen::Matrix<double, 12, 12> H = newtonMatrix(pair, x, blocks, &active, &friction);
    EXPECT_EQ(active, 0.0);  // the penalty does not act, the friction does
    EXPECT_NEAR(friction, pair.muLambda * ipcF1OverY(y, pair.slipEps),
                1e-12 * pair.muLambda / pair.slipEps);
    const double cw[4] = {1, -pair.weight[0], -pair.weight[1], -pair.weight[2]};
    Eigen::Matrix3d P = Eigen::Matrix3d::Identity();
    P(2, 2) = 0;  // the held normal is +z
    Eigen::Matrix<double, 12, 12> expected;
    for (int a = 0; a < 4; ++a)
      for (int b = 0; b < 4; ++b)
        expected.block<3, 3>(3 * a, 3 * b) =
            cw[a] * cw[b] * pair.muLambda * ipcF1OverY(y, pair.slipEps) * P;
    EXPECT_LT((H - expected).norm(), 1e-12 * expected.norm()) << "slide " << y << " m";
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix<double, 12, 12>> eig(H);
    EXPECT_GT(eig.eigenvalues().minCoeff(), -1e-9 * eig.eigenvalues().maxCoeff());
  }
}

}  // namespace
}  // namespace gf
