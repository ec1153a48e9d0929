// The condensed MPC's gradient map in the stack's order, shared by the synchronous step
// (HierarchicalStep) and the planner thread (PlanThread) so that both form G = Fᵀ S from the
// same matrix, bit for bit.
#pragma once

#include "hmpc/types.hpp"

namespace hmpc {

// The map F ((2 + 2N)×Nc, CondensedMPC.FT: rows q, q̇, then r_j, ṙ_j interleaved at rows
// 2 + 2(j-1), 3 + 2(j-1)) with its rows in the stack's order S = [q; q̇; r_1..r_N; ṙ_1..ṙ_N].
inline RowMat map_in_stack_order(const CRefRow& F, int N) {
  RowMat FT(2 + 2 * N, F.cols());
  FT.topRows(2) = F.topRows(2);
  for (int j = 0; j < N; ++j) {
    FT.row(2 + j) = F.row(2 + 2 * j);
    FT.row(2 + N + j) = F.row(3 + 2 * j);
  }
  return FT;
}

// The rows of that map the gradient needs: without a velocity weight the ṙ rows are zero
// and skipped (N + 2), else all (2 + 2N).
inline Eigen::Index gradient_rows(const RowMat& FT, int N) {
  return FT.bottomRows(N).isZero(0.0) ? N + 2 : 2 + 2 * N;
}

}  // namespace hmpc
