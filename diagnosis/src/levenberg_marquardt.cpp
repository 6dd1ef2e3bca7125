#include "levenberg_marquardt.hpp"

#include <Eigen/Cholesky>
#include <cmath>

namespace lw::diagnosis::detail {

LmResult MinimiseLeastSquares(const ResidualFn& fn, Eigen::VectorXd x0, const Eigen::VectorXd& lower,
                              const Eigen::VectorXd& upper, const Eigen::VectorXd& scale, int max_iterations) {
  const Eigen::Index n = x0.size();
  auto project = [&](Eigen::VectorXd& x) { x = x.cwiseMax(lower).cwiseMin(upper); };
  project(x0);
  LmResult result;
  Eigen::VectorXd x = x0, r, r_try, r_step;
  fn(x, r);
  double cost = r.squaredNorm();
  Eigen::MatrixXd jac(r.size(), n);
  double lambda = 1e-3;
  auto jacobian = [&](const Eigen::VectorXd& at, const Eigen::VectorXd& r_at) {
    jac.resize(r_at.size(), n);
    for (Eigen::Index k = 0; k < n; ++k) {
      double h = 1e-5 * std::max(scale[k], std::fabs(at[k]));
      Eigen::VectorXd xs = at;
      if (xs[k] + h > upper[k]) h = -h;
      xs[k] += h;
      fn(xs, r_step);
      jac.col(k) = (r_step - r_at) / h;
    }
  };
  int it = 0;
  for (; it < max_iterations; ++it) {
    jacobian(x, r);
    const Eigen::MatrixXd a = jac.transpose() * jac;
    const Eigen::VectorXd g = jac.transpose() * r;
    bool improved = false;
    double new_cost = cost;
    Eigen::VectorXd x_new;
    while (lambda < 1e12) {
      Eigen::MatrixXd damped = a;
      for (Eigen::Index k = 0; k < n; ++k) damped(k, k) += lambda * std::max(a(k, k), 1e-12) + 1e-15;
      const Eigen::VectorXd delta = damped.ldlt().solve(-g);
      x_new = x + delta;
      project(x_new);
      fn(x_new, r_try);
      new_cost = r_try.squaredNorm();
      if (std::isfinite(new_cost) && new_cost < cost) {
        improved = true;
        break;
      }
      lambda *= 4.0;
    }
    if (!improved) break;
    const double gain = cost - new_cost;
    x = x_new;
    r = r_try;
    cost = new_cost;
    lambda = std::max(lambda / 3.0, 1e-9);
    if (gain < 1e-7 * cost + 1e-10) break;
  }
  jacobian(x, r);
  result.x = x;
  result.cost = cost;
  result.jtj = jac.transpose() * jac;
  result.iterations = it;
  return result;
}

}  // namespace lw::diagnosis::detail
