#pragma once
/// A small bounded Levenberg-Marquardt least-squares solver with a numeric (forward-difference)
/// Jacobian. Bounds are kept by projection.
#include <Eigen/Core>
#include <functional>

namespace lw::diagnosis::detail {

using ResidualFn = std::function<void(const Eigen::VectorXd& x, Eigen::VectorXd& residuals)>;

struct LmResult {
  Eigen::VectorXd x;
  double cost = 0;      ///< sum of squared residuals at x
  Eigen::MatrixXd jtj;  ///< J^T J at x (inverse = covariance when residuals are whitened)
  int iterations = 0;
};

LmResult MinimiseLeastSquares(const ResidualFn& fn, Eigen::VectorXd x0, const Eigen::VectorXd& lower,
                              const Eigen::VectorXd& upper, const Eigen::VectorXd& scale, int max_iterations = 60);

}  // namespace lw::diagnosis::detail
