// Material presets and parameter checks (public gf::Material).
#include <cmath>
#include <string>

#include "graphfrac/defs.h"

namespace gf {

namespace {
Material make(MaterialModel model, double E, double nu, double rho) {
  Material m;
  m.model = model;
  m.youngsModulus = E;
  m.poissonRatio = nu;
  m.density = rho;
  return m;
}
bool positiveFinite(double v) { return std::isfinite(v) && v > 0; }
}  // namespace

Material Material::corotated(double E, double nu, double rho) {
  return make(MaterialModel::Corotated, E, nu, rho);
}
Material Material::stvk(double E, double nu, double rho) {
  return make(MaterialModel::StVK, E, nu, rho);
}
Material Material::neoHookean(double E, double nu, double rho) {
  return make(MaterialModel::NeoHookean, E, nu, rho);
}
Material Material::stableNeoHookean(double E, double nu, double rho) {
  return make(MaterialModel::StableNeoHookean, E, nu, rho);
}

Result<void> Material::check() const {
  if (static_cast<unsigned>(model) > 3u)
    return fail("material.model: unknown model ", std::to_string(static_cast<int>(model)));
  if (!positiveFinite(youngsModulus))
    return fail("material.youngsModulus: must be positive and finite, got ",
                std::to_string(youngsModulus));
  // nu -> 0.5 makes lambda (eq 4.29) infinite; nu <= -1 makes mu negative.
  if (!std::isfinite(poissonRatio) || poissonRatio <= -1.0 || poissonRatio >= 0.5)
    return fail("material.poissonRatio: must lie in (-1, 0.5), got ", std::to_string(poissonRatio));
  if (!positiveFinite(density))
    return fail("material.density: must be positive and finite, got ", std::to_string(density));
  if (!std::isfinite(fibreStiffness) || fibreStiffness < 0)
    return fail("material.fibreStiffness: must be >= 0 and finite, got ",
                std::to_string(fibreStiffness));
  if (fibreStiffness > 0) {
    const double len2 = double(fibreDirection.x) * fibreDirection.x +
                        double(fibreDirection.y) * fibreDirection.y +
                        double(fibreDirection.z) * fibreDirection.z;
    if (!std::isfinite(len2) || len2 < 1e-12)
      return fail("material.fibreDirection: must be a finite non-zero vector");
  }
  if (!std::isfinite(massDamping) || massDamping < 0)
    return fail("material.massDamping: must be >= 0 and finite, got ", std::to_string(massDamping));
  if (!std::isfinite(stiffnessDamping) || stiffnessDamping < 0)
    return fail("material.stiffnessDamping: must be >= 0 and finite, got ",
                std::to_string(stiffnessDamping));
  return {};
}

}  // namespace gf
