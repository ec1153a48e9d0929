// The arm's own joint dynamics: see joint_dynamics.hpp.
#include "hmpc/joint_dynamics.hpp"

#include "hmpc/small_dense.hpp"

#include <cmath>
#include <stdexcept>
#include <string>

namespace hmpc {

void JointDynamics::set(const CRefVec& damping, const CRefVec& friction, int n, const char* who) {
  if (damping.size() != n || friction.size() != n)
    throw std::invalid_argument(std::string(who) + ": damping and friction must be (n,)");
  if ((damping.array() < 0.0).any() || (friction.array() < 0.0).any() || !damping.allFinite() ||
      !friction.allFinite())
    throw std::invalid_argument(std::string(who) + ": expected finite values >= 0");
  b = damping;
  f = friction;
  any = (b.array() != 0.0).any() || (f.array() != 0.0).any();
}

void JointDynamics::zoh(const Mat& Mq, const Vec& dq, const double* v, double Ts, Vec& extra) {
  const auto n = b.size();
  extra.setZero(n);
  L_.resize(n, n);
  e_.resize(n);
  if (!cholesky(Mq, L_)) return;
  for (Eigen::Index j = 0; j < n; ++j) {
    if (b[j] == 0.0 && f[j] == 0.0) continue;
    // (M⁻¹)_jj = ‖L⁻¹ e_j‖² (M = L Lᵀ); without damping x = 0 needs none
    const double minv = b[j] != 0.0 ? inverse_diagonal(L_, j, e_) : 0.0;
    const double x = b[j] * minv * Ts;
    const double vj = v[j];
    if (b[j] != 0.0) {
      const double g = x < 1e-8 ? 1.0 + 0.5 * x : x / -std::expm1(-x);
      extra[j] = (g - 1.0) / minv * vj;
    }
    if (f[j] != 0.0) {
      const double a = dq[j], c = a + vj * Ts;
      const double sa = sgn(a), sc = sgn(c);
      double sigma = sc;
      if (sa != 0.0 && sa != sc) {
        const double p = a / (a - c);  // in (0, 1]: the crossing on a linear path
        double w1 = p;                 // weight of the part before the crossing
        if (x > 1e-8) {
          const double E = std::exp(-x);
          const double s_star = -std::log1p(-p * (1.0 - E)) / x;
          w1 = (std::exp(-x * (1.0 - s_star)) - E) / (1.0 - E);
        }
        sigma = sa * w1 + sc * (1.0 - w1);
      }
      extra[j] += f[j] * (sigma - sa);
    }
  }
}

}  // namespace hmpc
