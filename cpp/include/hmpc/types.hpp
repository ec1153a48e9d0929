// The Eigen types every unit of the library uses.
#pragma once

#include <Eigen/Core>

namespace hmpc {

using Vec = Eigen::VectorXd;
using Mat = Eigen::MatrixXd;
using RowMat = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
using CRefVec = Eigen::Ref<const Vec>;
using RefVec = Eigen::Ref<Vec>;
using CRefMat = Eigen::Ref<const Mat>;
using CRefRow = Eigen::Ref<const RowMat>;
using MapVec = Eigen::Map<Vec>;
using MapRow = Eigen::Map<RowMat>;

}  // namespace hmpc
