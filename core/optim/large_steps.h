// Large Steps in inverse rendering of geometry (Nicolet et al. 2021): a vertex parameter x is
// optimised as u = (I + lambda L) x, L the mesh's combinatorial Laplacian (degree on the diagonal,
// -1 per edge), and mapped back by solving (I + lambda L) x = u with a sparse Cholesky factor
// computed once per mesh. A gradient step in u moves x smoothly: the solve spreads each vertex's
// gradient over its neighbourhood, so noisy per-vertex gradients do not crumple the surface.
#pragma once

#include <cstdint>
#include <memory>
#include <utility>
#include <vector>

namespace invr {

class LargeSteps {
 public:
  // `vertices` of the parameter, `edges` between them (each once), lambda >= 0.
  LargeSteps(uint32_t vertices, const std::vector<std::pair<uint32_t, uint32_t>>& edges, double lambda);
  ~LargeSteps();
  LargeSteps(const LargeSteps&) = delete;
  LargeSteps& operator=(const LargeSteps&) = delete;

  // xyz interleaved per vertex, as the parameter stores them.
  std::vector<double> toU(const std::vector<double>& x) const;    // u = (I + lambda L) x
  std::vector<double> solve(const std::vector<double>& u) const;  // x with (I + lambda L) x = u

  uint32_t vertices() const { return vertices_; }

 private:
  struct Factor;
  uint32_t vertices_;
  double lambda_;
  std::vector<std::pair<uint32_t, uint32_t>> edges_;
  std::vector<double> degree_;
  std::unique_ptr<Factor> factor_;
};

}  // namespace invr
