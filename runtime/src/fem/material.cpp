// Material presets (public gf::Material); Material::check lives with the other checks.
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

}  // namespace gf
