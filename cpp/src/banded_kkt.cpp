// The soft QP's KKT subproblem by an envelope LDLᵀ in banded coordinates: see banded_kkt.hpp.
#include "hmpc/banded_kkt.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace hmpc {

BandedKKT::BandedKKT(const Mat& T, const Mat& E, const Mat& Hp, const Mat& H,
                     const GammaRecursion& gamma, const Vec& row_scale, double k_slack,
                     double hss, double eps_abs)
    : N_(static_cast<int>(E.rows() / 2)), Nc_(static_cast<int>(T.rows())), T_(T), E_(E),
      Hp_(Hp), H_(H), gamma_(&gamma), row_scale_(row_scale), k_(k_slack), hss_(hss),
      eps_abs_(eps_abs) {
  const int Nc = Nc_, N = N_;
  if (T.cols() != Nc || E.rows() != 2 * N || E.cols() != Nc || Hp.rows() != Nc ||
      Hp.cols() != Nc || H.rows() != Nc || H.cols() != Nc || row_scale.size() != 4 * N)
    throw std::invalid_argument(
        "BandedKKT: T, Hp, H must be (Nc, Nc), E (2N, Nc) and row_scale (4N,)");
  // The bands: T lower triangular, each row of E one contiguous run of columns, Hp of lower
  // bandwidth wH_ (every entry outside them exactly zero, as CondensedMPC.banded makes them).
  for (int a = 0; a < Nc; ++a)
    for (int c = 0; c < a; ++c)
      if (Hp_(a, c) != 0.0) wH_ = std::max(wH_, a - c);
  t_first_.assign(Nc, 0);
  for (int a = 0; a < Nc; ++a) {
    int f = a;
    for (int c = 0; c < Nc; ++c) {
      if (T_(a, c) == 0.0) continue;
      if (c > a) throw std::invalid_argument("JointQPs.set_limits: T must be lower triangular");
      f = std::min(f, c);
    }
    t_first_[a] = f;
    wT_ = std::max(wT_, a - f);
  }
  e_first_.assign(2 * N, 0);
  e_last_.assign(2 * N, 0);
  rows_by_last_.assign(Nc, {});
  for (int r = 0; r < 2 * N; ++r) {
    int f = -1, l = -1;
    for (int c = 0; c < Nc; ++c)
      if (E_(r, c) != 0.0) {
        if (f < 0) f = c;
        l = c;
      }
    if (f < 0) throw std::invalid_argument("JointQPs.set_limits: a row of E is zero");
    e_first_[r] = f;
    e_last_[r] = l;
    rows_by_last_[l].push_back(r);
  }
  pidx_.assign(Nc, 0);
  const int items = 2 * Nc + 2 * N + 1;
  item_kind_.reserve(items);
  item_ref_.reserve(items);
  first_.reserve(items);
  start_.reserve(items + 1);
  D_.assign(items, 0.0);
  w_.assign(items, 0.0);
  x_.assign(items, 0.0);
  y_.setZero(Nc + 1);
  lam_.setZero(2 * N);
  rU_.setZero(Nc);
  mu_.setZero(Nc);
  gl_.setZero(Nc);
  Xs_.setZero(2 * N);
}

void BandedKKT::project(const Vec& g, Vec& gp) const {
  gp.setZero();
  for (int a = 0; a < Nc_; ++a)
    for (int c = t_first_[a]; c <= a; ++c) gp[c] += T_(a, c) * g[a];
}

bool BandedKKT::solve(SoftActiveSet& st, const SoftProblem& p) {
  dropped_ = false;
  assemble(st, p);
  if (!factor(st)) return false;
  substitute();
  extract();
  if (!(std::isfinite(y_.sum()) && std::isfinite(lam_.sum()))) return false;
  refine(st, p);
  return std::isfinite(y_.sum()) && std::isfinite(lam_.sum());
}

// The items in the KKT matrix's order and its rows' envelopes, with the right-hand side in x_.
void BandedKKT::assemble(const SoftActiveSet& st, const SoftProblem& p) {
  const int Nc = Nc_;
  item_kind_.clear();
  item_ref_.clear();
  first_.clear();
  // A free ŝ first: rows tied through it (e.g. two rows at the largest violation) are
  // dependent in p alone. Each active row's envelope then reaches back to it.
  const bool slack_free = st.slack != 0;
  if (slack_free) {
    item_kind_.push_back(3);
    item_ref_.push_back(Nc);
    first_.push_back(0);
  }
  for (int a = 0; a < Nc; ++a) {
    pidx_[a] = static_cast<int>(item_kind_.size());
    item_kind_.push_back(0);
    item_ref_.push_back(a);
    first_.push_back(pidx_[std::max(a - wH_, 0)]);
    if (st.box[a] != 0) {
      item_kind_.push_back(1);
      item_ref_.push_back(a);
      first_.push_back(pidx_[t_first_[a]]);
    }
    for (int r : rows_by_last_[a]) {
      if (st.rows[r] == 0) continue;
      item_kind_.push_back(2);
      item_ref_.push_back(r);
      first_.push_back(slack_free ? 0 : pidx_[e_first_[r]]);
    }
  }
  const int m = static_cast<int>(item_kind_.size());
  start_.resize(m + 1);
  start_[0] = 0;
  for (int k = 0; k < m; ++k) start_[k + 1] = start_[k] + (k - first_[k] + 1);
  L_.assign(start_[m], 0.0);
  auto at = [&](int k, int col) -> double& { return L_[start_[k] + col - first_[k]]; };
  for (int k = 0; k < m; ++k) {
    const int ref = item_ref_[k];
    switch (item_kind_[k]) {
      case 0:
        for (int c = std::max(ref - wH_, 0); c <= ref; ++c) at(k, pidx_[c]) = Hp_(ref, c);
        x_[k] = -p.gp[ref];
        break;
      case 1:
        for (int c = t_first_[ref]; c <= ref; ++c) at(k, pidx_[c]) = T_(ref, c);
        x_[k] = st.box[ref] < 0 ? p.lo : p.hi;
        break;
      case 2:
        for (int c = e_first_[ref]; c <= e_last_[ref]; ++c) at(k, pidx_[c]) = E_(ref, c);
        if (slack_free) at(k, 0) = -k_ * st.rows[ref];
        x_[k] = st.rows[ref] > 0 ? p.bnd_hi[ref] : p.bnd_lo[ref];
        break;
      default:
        at(k, k) = hss_;
        x_[k] = -p.g[Nc];
    }
  }
}

// Envelope LDLᵀ (row k holds L(k, first_[k] .. k−1) and, at k, the diagonal). False at a
// pivot of the wrong sign or negligible: a bound or row dependent on those before it (e.g.
// an input at its bound between two active velocity rows, which fix it to 0) leaves st
// (dropped_), the next exchange tests it; a p's or ŝ's pivot: no answer.
bool BandedKKT::factor(SoftActiveSet& st) {
  const int m = static_cast<int>(item_kind_.size());
  for (int k = 0; k < m; ++k) {
    const int fk = first_[k];
    double* Lk = L_.data() + start_[k] - fk;
    double size = std::abs(Lk[k]);
    for (int j = fk; j < k; ++j) {
      const int fj = first_[j];
      const double* Lj = L_.data() + start_[j] - fj;
      double s = Lk[j];
      for (int c = std::max(fk, fj); c < j; ++c) s -= w_[c] * Lj[c];
      w_[j] = s;
      Lk[j] = s / D_[j];
    }
    double d = Lk[k];
    for (int c = fk; c < k; ++c) {
      d -= Lk[c] * w_[c];
      size += std::abs(Lk[c] * w_[c]);
    }
    const double sign = item_kind_[k] == 0 || item_kind_[k] == 3 ? 1.0 : -1.0;
    if (!(sign * d > 1e-13 * size)) {  // NaN too
      if (item_kind_[k] == 0 || item_kind_[k] == 3) return false;
      // A row whose dependency holds an input at its bound frees the last such input (the
      // rows are the limits, and with both kept the exchanges re-add the dropped row at
      // every step: a cycle); otherwise the item itself.
      const int drop = item_kind_[k] == 2 && std::isfinite(d) ? dependent_bound(k, fk, Lk) : k;
      if (item_kind_[drop] == 1) st.box[item_ref_[drop]] = 0;
      else st.rows[item_ref_[drop]] = 0;
      dropped_ = true;
      return false;
    }
    D_[k] = d;
  }
  return true;
}

// Row item k's dependency a_k = Σ_j ρ_j a_j: K_{<k} [0; ρ] = [a_k; 0], so ρ is the constraint
// part of K_{<k}⁻¹ b_k = L⁻ᵀ (row k of L), b_k the column of item k. Returns the last bound
// item with a weight above 1e-9 of the largest, else k.
int BandedKKT::dependent_bound(int k, int fk, const double* Lk) {
  z_.resize(D_.size());
  for (int j = 0; j < k; ++j) z_[j] = j >= fk ? Lk[j] : 0.0;
  for (int j = k - 1; j > 0; --j) {
    const int fj = first_[j];
    const double* Lj = L_.data() + start_[j] - fj;
    const double zj = z_[j];
    if (zj != 0.0)
      for (int c = fj; c < j; ++c) z_[c] -= Lj[c] * zj;
  }
  double big = 0.0;
  for (int j = 0; j < k; ++j)
    if (item_kind_[j] == 1 || item_kind_[j] == 2) big = std::max(big, std::abs(z_[j]));
  for (int j = k - 1; j >= 0; --j)
    if (item_kind_[j] == 1 && std::abs(z_[j]) > 1e-9 * big) return j;
  return k;
}

// x_ ← K⁻¹ x_ with the envelope LDLᵀ of factor.
void BandedKKT::substitute() {
  const int m = static_cast<int>(item_kind_.size());
  for (int k = 0; k < m; ++k) {  // L z = b
    const int fk = first_[k];
    const double* Lk = L_.data() + start_[k] - fk;
    double s = x_[k];
    for (int c = fk; c < k; ++c) s -= Lk[c] * x_[c];
    x_[k] = s;
  }
  for (int k = 0; k < m; ++k) x_[k] /= D_[k];
  for (int k = m - 1; k >= 0; --k) {  // Lᵀ x = z
    const int fk = first_[k];
    const double* Lk = L_.data() + start_[k] - fk;
    const double xk = x_[k];
    for (int c = fk; c < k; ++c) x_[c] -= Lk[c] * xk;
  }
}

// y_, lam_, mu_ from the solution x_ (U = T p).
void BandedKKT::extract() {
  const int m = static_cast<int>(item_kind_.size()), Nc = Nc_;
  lam_.setZero();
  mu_.setZero();
  y_[Nc] = 0.0;
  for (int k = 0; k < m; ++k) {
    if (item_kind_[k] == 1) mu_[item_ref_[k]] = x_[k];
    else if (item_kind_[k] == 2) lam_[item_ref_[k]] = x_[k];
    else if (item_kind_[k] == 3) y_[Nc] = x_[k];
  }
  for (int a = 0; a < Nc; ++a) {  // U = T p
    double u = 0.0;
    for (int c = t_first_[a]; c <= a; ++c) u += T_(a, c) * x_[pidx_[c]];
    y_[a] = u;
  }
}

// Iterative refinement against the KKT system in U (the solver's H, Γ): U = T p is a
// second difference of p, whose rounding would otherwise reach the gradient's tolerance.
// Refined (twice at most) only while the residual (the gradient's in U, the rows' as the
// solver scales them, the bounds', ŝ's when free) exceeds 1e-3 of the solver's absolute
// tolerance.
void BandedKKT::refine(const SoftActiveSet& st, const SoftProblem& p) {
  const int m = static_cast<int>(item_kind_.size()), Nc = Nc_, N = N_;
  for (int refine = 0; refine < 2; ++refine) {
    const auto u = y_.head(Nc);
    rU_.noalias() = H_ * u;
    rU_ += p.g.head(Nc);
    gamma_->apply_transpose(lam_, gl_);
    rU_ += gl_;
    rU_ += mu_;
    gamma_->apply(u, Xs_);
    double rs = hss_ * y_[Nc] + p.g[Nc];
    for (int r = 0; r < 2 * N; ++r) rs -= k_ * st.rows[r] * lam_[r];
    for (int k = 0; k < m; ++k) {
      const int ref = item_ref_[k];
      switch (item_kind_[k]) {
        case 0: {
          double t = 0.0;  // (Tᵀ r)_ref
          for (int a = ref; a < Nc && a <= ref + wT_; ++a)
            if (t_first_[a] <= ref) t += T_(a, ref) * rU_[a];
          x_[k] = -t;
          break;
        }
        case 1: x_[k] = (st.box[ref] < 0 ? p.lo : p.hi) - y_[ref]; break;
        case 2:
          x_[k] = (st.rows[ref] > 0 ? p.bnd_hi[ref] : p.bnd_lo[ref]) -
                  (Xs_[ref] - k_ * st.rows[ref] * y_[Nc]);
          break;
        default: x_[k] = -rs;
      }
    }
    double res = rU_.cwiseAbs().maxCoeff();
    for (int k = 0; k < m; ++k) {
      const int ref = item_ref_[k];
      if (item_kind_[k] == 1) res = std::max(res, std::abs(x_[k]));
      else if (item_kind_[k] == 2) res = std::max(res, std::abs(x_[k]) * scale(ref));
      else if (item_kind_[k] == 3) res = std::max(res, std::abs(rs));
    }
    if (!(res > 1e-3 * eps_abs_)) break;
    substitute();
    for (int k = 0; k < m; ++k) {
      const int ref = item_ref_[k];
      if (item_kind_[k] == 1) mu_[ref] += x_[k];
      else if (item_kind_[k] == 2) lam_[ref] += x_[k];
      else if (item_kind_[k] == 3) y_[Nc] += x_[k];
    }
    for (int a = 0; a < Nc; ++a) {
      double du = 0.0;
      for (int c = t_first_[a]; c <= a; ++c) du += T_(a, c) * x_[pidx_[c]];
      y_[a] += du;
    }
  }
}

}  // namespace hmpc
