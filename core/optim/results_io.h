// Writing an optimisation's results: parameters as JSON (textures also as EXR images a person can
// look at) and the convergence CSV. The one writer of both for `invr optimize`, the server's job
// runner and `invr-lab eval` (same files, columns and precision).
#pragma once

#include <filesystem>
#include <limits>
#include <optional>
#include <string>
#include <vector>

#include "core/diff/parameters.h"
#include "invr/v1/stats.pb.h"

namespace invr {

// Writes dir/parameters.json, dir/<name>.exr per texture parameter and dir/mesh_<shape>.ply per
// vertex parameter (parameters.json then names the file instead of listing the numbers); returns
// the files written.
std::vector<std::string> writeParameters(const std::filesystem::path& dir, const ParameterRegistry& params,
                                         const std::vector<float>& theta, const Scene& scene);
// The inverse of writeParameters: the values of `dir`/parameters.json (textures from their EXR,
// vertex parameters from their PLY, one vertex per parameter vertex) written into `theta`, which
// holds one value per parameter of `params`. Errors name the file and the parameter.
void readParameters(const std::filesystem::path& dir, const ParameterRegistry& params, std::vector<float>& theta);

class Scene;

// Jobs with sampling parameters (docs/variance.md): the light-selection probabilities they reached.
// dir/light_selection.csv (light,probability) holds the global rule; each view with per-pixel logits
// gets dir/selection_view<v>.exr, one channel per light (named after it) per cell of its map.
// Writes theta into `scene`; returns the files written (none without sampling parameters).
std::vector<std::string> writeSelectionResults(const std::filesystem::path& dir, const ParameterRegistry& params, Scene& scene,
                                               const std::vector<float>& theta);

// The values of the scalar and small parameters (at most maxValues each, no textures or meshes) at
// theta, for progress events: name and values.
std::vector<std::pair<std::string, std::vector<double>>> smallParameterValues(const ParameterRegistry& params, const std::vector<float>& theta,
                                                                               uint32_t maxValues = 16);

// convergence.csv: one row per step (and eval's step 0), columns
//   method, step, seconds, loss, param_error, image_error, [shape_error: jobs with vertex parameters,]
//   [image_loss: runs that report it (smoothed one-render loss, smoothed_loss.h),]
// then every field of the step's GradientStats (but its loss: the loss column) by its proto path
// (seconds_primal, rays.camera, drops.primal, boundary.<term>.samples,
// boundary.<term>.counters.<name>, ...; map entries by key), a column added when first seen. A cell is empty
// where a value was not measured (loss at step 0, image error between checkpoints, statistics at
// step 0); numbers have 9 significant digits, counts are exact; param_error is -1 for jobs without
// ground truth.
struct ConvergenceRow {
  std::string method;
  uint64_t step = 0;
  double seconds = 0;
  double loss = std::numeric_limits<double>::quiet_NaN();
  double paramError = std::numeric_limits<double>::quiet_NaN();
  double imageError = std::numeric_limits<double>::quiet_NaN();
  std::optional<invr::v1::GradientStats> stats;
  double shapeError = std::numeric_limits<double>::quiet_NaN();  // a column only when some row has one
  double imageLoss = std::numeric_limits<double>::quiet_NaN();   // a column only when some row has one
};

class ConvergenceCsv {
 public:
  explicit ConvergenceCsv(std::filesystem::path path) : path_(std::move(path)) {}
  void add(ConvergenceRow row) { rows_.push_back(std::move(row)); }
  size_t rows() const { return rows_.size(); }
  // (Re)writes the file with every row so far; the statistics' columns are the union over rows
  // (map keys in the order first seen). Throws InputError when the file cannot be written.
  void write() const;

 private:
  std::filesystem::path path_;
  std::vector<ConvergenceRow> rows_;
};

}  // namespace invr
