#include "core/optim/large_steps.h"

#include <Eigen/SparseCholesky>
#include <Eigen/SparseCore>
#include <stdexcept>

namespace invr {

struct LargeSteps::Factor {
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> ldlt;
};

LargeSteps::LargeSteps(uint32_t vertices, const std::vector<std::pair<uint32_t, uint32_t>>& edges, double lambda)
    : vertices_(vertices), lambda_(lambda), edges_(edges), degree_(vertices, 0.0), factor_(std::make_unique<Factor>()) {
  if (!(lambda >= 0)) throw std::invalid_argument("LargeSteps: lambda must be >= 0");
  std::vector<Eigen::Triplet<double>> t;
  t.reserve(vertices + 2 * edges.size());
  for (const auto& [a, b] : edges) {
    degree_[a] += 1;
    degree_[b] += 1;
    t.emplace_back(int(a), int(b), -lambda);
    t.emplace_back(int(b), int(a), -lambda);
  }
  for (uint32_t v = 0; v < vertices; ++v) t.emplace_back(int(v), int(v), 1.0 + lambda * degree_[v]);
  const int n = int(vertices);
  Eigen::SparseMatrix<double> m(n, n);
  m.setFromTriplets(t.begin(), t.end());
  // I + lambda L is symmetric positive definite for lambda >= 0 (L is positive semi-definite).
  factor_->ldlt.compute(m);
  if (factor_->ldlt.info() != Eigen::Success) throw std::runtime_error("LargeSteps: the Cholesky factorisation of I + lambda L failed");
}

LargeSteps::~LargeSteps() = default;

std::vector<double> LargeSteps::toU(const std::vector<double>& x) const {
  if (x.size() != 3 * size_t(vertices_)) throw std::invalid_argument("LargeSteps::toU: size mismatch");
  std::vector<double> u(x.size());
  for (uint32_t v = 0; v < vertices_; ++v)
    for (int c = 0; c < 3; ++c) u[3 * v + c] = (1.0 + lambda_ * degree_[v]) * x[3 * v + c];
  for (const auto& [a, b] : edges_)
    for (int c = 0; c < 3; ++c) {
      u[3 * a + c] -= lambda_ * x[3 * b + c];
      u[3 * b + c] -= lambda_ * x[3 * a + c];
    }
  return u;
}

std::vector<double> LargeSteps::solve(const std::vector<double>& u) const {
  if (u.size() != 3 * size_t(vertices_)) throw std::invalid_argument("LargeSteps::solve: size mismatch");
  Eigen::MatrixXd rhs(int(vertices_), 3);
  for (uint32_t v = 0; v < vertices_; ++v)
    for (int c = 0; c < 3; ++c) rhs(int(v), c) = u[3 * v + c];
  const Eigen::MatrixXd x = factor_->ldlt.solve(rhs);
  std::vector<double> out(u.size());
  for (uint32_t v = 0; v < vertices_; ++v)
    for (int c = 0; c < 3; ++c) out[3 * v + c] = x(int(v), c);
  return out;
}

}  // namespace invr
