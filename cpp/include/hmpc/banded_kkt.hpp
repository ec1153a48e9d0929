// The soft-limit QP's equality-constrained subproblem for a given active set, solved in
// banded coordinates by an envelope LDLᵀ of its KKT matrix in O(N). The soft QP's variables
// are y = (U, ŝ), s = k ŝ; with the active set (each row r of X = Γ U, interleaved
// q_1, q̇_1, …: −1 at its lower bound, +1 at its upper, 0 free; each input at v_min, v_max or
// free; ŝ free or at its bound 0) it solves
//     min ½ yᵀ Hs y + gᵀ y  s.t.  Γ_r U − st_r k ŝ = b_r (active rows), u_a = bound (active box)
// with Hs = diag(H, hss), in the coordinates U = T p (Hp = Tᵀ H T, E = Γ T, each exactly
// banded; hmpc_pin.mpc.condensed.CondensedMPC.banded): its KKT matrix
// [hss, ·, cᵀ; ·, Hp, Eᵀ; c, E, 0], ŝ (when free) first, each active row placed right after
// the last p it involves, has an envelope of a few entries per row (with ŝ free, the rows
// reach back to it), so its LDLᵀ without pivoting (quasi-definite: positive pivots for ŝ
// and p, negative for the rows) costs O(N) (O(N · active rows) with ŝ free). The answer is
// refined against the KKT system in U (H, Γ). SoftLimits (soft_limits.hpp) calls it at
// each exchange. Oracle: numpy.linalg.solve of the dense KKT system
// (tests/reference/qp_parts.py).
#pragma once

#include "hmpc/gamma_recursion.hpp"

#include <Eigen/Core>

#include <vector>

namespace hmpc {

// An active set of the soft QP: rows (2N) and box (Nc) −1 lower, +1 upper, 0 inactive;
// slack 1 when ŝ is free, 0 at its bound 0.
struct SoftActiveSet {
  std::vector<signed char> rows, box;
  signed char slack = 0;
};

// One joint's soft QP at a step, in the subproblem's terms: g (Nc + 1), the gradient of
// (U, ŝ); gp = Tᵀ g_U (BandedKKT::project); the box [lo, hi]; the rows' bounds on
// Γ_r U − k s ŝ (2N, rows in Γ's order).
struct SoftProblem {
  Eigen::VectorXd g, gp, bnd_lo, bnd_hi;
  double lo = 0.0, hi = 0.0;
};

class BandedKKT {
 public:
  using Vec = Eigen::VectorXd;
  using Mat = Eigen::MatrixXd;

  // T lower triangular (Nc×Nc), E (2N×Nc) each row one contiguous run, Hp (Nc×Nc) banded,
  // every entry outside the bands exactly zero; H (Nc×Nc); gamma: Γ's products (kept by the
  // caller, alive as long as this); row_scale (4N): the solver's row scaling (the residual
  // test's units); k_slack, hss: s = k ŝ and ŝ's Hessian entry; eps_abs: the refinement
  // stops below 1e-3 of it.
  BandedKKT(const Mat& T, const Mat& E, const Mat& Hp, const Mat& H,
            const GammaRecursion& gamma, const Vec& row_scale, double k_slack, double hss,
            double eps_abs);

  // gp = Tᵀ g_U (g of Nc + 1).
  void project(const Vec& g, Vec& gp) const;

  // Solve the subproblem of the active set st for p. Writes y() (Nc + 1), lam() (2N, the
  // rows' multipliers: Hs y + g + [Γᵀλ + μ; −k Σ s_r λ_r] = 0) and mu() (Nc, the bounds').
  // False if a pivot has the wrong sign or is negligible: dropped() when that pivot's bound
  // or row, dependent on those before it, has been left out of st.
  bool solve(SoftActiveSet& st, const SoftProblem& p);
  bool dropped() const { return dropped_; }
  Vec& y() { return y_; }
  const Vec& lam() const { return lam_; }
  const Vec& mu() const { return mu_; }

  // The solver's scaling of row r (of Γ's order).
  double scale(int r) const { return row_scale_[(r % 2 == 0 ? 0 : 2 * N_) + r / 2]; }

 private:
  void assemble(const SoftActiveSet& st, const SoftProblem& p);
  bool factor(SoftActiveSet& st);
  int dependent_bound(int k, int fk, const double* Lk);
  void substitute();
  void extract();
  void refine(const SoftActiveSet& st, const SoftProblem& p);

  int N_, Nc_;
  Mat T_, E_, Hp_, H_;
  const GammaRecursion* gamma_;
  Vec row_scale_;
  double k_, hss_, eps_abs_;
  int wH_ = 0, wT_ = 0;
  std::vector<int> t_first_, e_first_, e_last_;
  std::vector<std::vector<int>> rows_by_last_;
  // The envelope LDLᵀ: per item (0 a p, 1 a bound, 2 a row, 3 ŝ) its reference, the first
  // column of its row of L and where that row starts in L_.
  bool dropped_ = false;
  std::vector<int> item_kind_, item_ref_, first_, start_, pidx_;
  std::vector<double> L_, D_, w_, x_, z_;
  Vec y_, lam_, mu_, rU_, gl_, Xs_;
};

}  // namespace hmpc
