// One box QP with its cold twin: see box_qp.hpp.
#include "hmpc/box_qp.hpp"

#include <proxsuite/proxqp/dense/dense.hpp>

#include <optional>

namespace hmpc {

namespace pqp = proxsuite::proxqp;

BoxQP::BoxQP(const Mat& H, const Vec& lo, const Vec& hi, const QPSettings& warm,
             const QPSettings& cold)
    : H_(H), lo_(lo), hi_(hi), warm_(warm), cold_(cold) {
  restart();
}

BoxQP::~BoxQP() = default;

const BoxQP::Results& BoxQP::failed() const { return cold_qp_->results; }

void BoxQP::restart() {
  auto qp = std::make_unique<DenseQP>(H_.rows(), 0, 0, true);
  warm_.apply(qp->settings);
  const Vec g = Vec::Zero(H_.rows());
  qp->init(H_, g, std::nullopt, std::nullopt, std::nullopt, std::nullopt, std::nullopt, lo_, hi_);
  qp->solve();
  qp_ = std::move(qp);
  res_ = &qp_->results;
  cold_qp_.reset();
}

const BoxQP::Results* BoxQP::solve(const Vec& g, int shift_block, bool& cold) {
  cold = false;
  DenseQP& qp = *qp_;
  if (shift_block > 1) {  // warm start from the last solution, one step on
    auto& x = qp.results.x;
    auto& z = qp.results.z;
    const int blocks = static_cast<int>(x.size()) / shift_block;
    for (int b = 0; b < blocks; ++b) {
      const int o = b * shift_block;
      for (int j = 0; j + 1 < shift_block; ++j) {
        x[o + j] = x[o + j + 1];
        z[o + j] = z[o + j + 1];
      }
    }
  }
  qp.update(std::nullopt, g, std::nullopt, std::nullopt, std::nullopt, std::nullopt,
            std::nullopt, std::nullopt, std::nullopt);
  qp.solve();
  if (qp.results.info.status == pqp::QPSolverOutput::PROXQP_SOLVED) return &qp.results;
  if (!cold_qp_) {
    auto twin = std::make_unique<DenseQP>(H_.rows(), 0, 0, true);
    cold_.apply(twin->settings);
    twin->init(H_, g, std::nullopt, std::nullopt, std::nullopt, std::nullopt, std::nullopt, lo_,
               hi_);
    twin->solve();
    cold_qp_ = std::move(twin);
  } else {
    cold_qp_->update(std::nullopt, g, std::nullopt, std::nullopt, std::nullopt, std::nullopt,
                     std::nullopt, std::nullopt, std::nullopt);
    cold_qp_->solve();
  }
  const auto& res = cold_qp_->results;
  if (res.info.status != pqp::QPSolverOutput::PROXQP_SOLVED) return nullptr;
  cold = true;
  // Restart the warm QP from this solution, so that the next steps warm-start from it.
  Vec x = res.x, y = res.y;
  qp.solve(x, y, std::nullopt);
  if (qp.results.info.status == pqp::QPSolverOutput::PROXQP_SOLVED) return &qp.results;
  return &res;
}

void BoxQP::set_max_iter(long max_iter) {
  warm_.max_iter = cold_.max_iter = max_iter;
  qp_->settings.max_iter = max_iter;
  if (cold_qp_) cold_qp_->settings.max_iter = max_iter;
}

}  // namespace hmpc
