// loss_grad pixel sampling (Su & Gkioulekas 2024): p_j proportional to |dL/dI_j|, from stage 1.
#include "core/diff/pixel_sampler.h"

#include <cmath>

namespace invr {

std::vector<float> lossGradMap(const Stage1& s) {
  std::vector<float> cells(size_t(s.gw) * size_t(s.gh));
  for (size_t i = 0; i < cells.size(); ++i)
    cells[i] = s.adjointAbs[3 * i] + s.adjointAbs[3 * i + 1] + s.adjointAbs[3 * i + 2];
  return cells;
}

namespace {

class LossGradPixels final : public PixelSampler {
 public:
  const char* name() const override { return "loss_grad"; }
  bool usesStage1() const override { return true; }
  std::vector<float> cellValues(const Stage1& s, const PixelSamplingOptions&) const override { return lossGradMap(s); }
  std::string describe(const PixelSamplingOptions& o) const override { return "p_j ~ |dL/dI_j| (Su & Gkioulekas 2024)" + stage1HistoryNote(o); }
  void parseOptions(const invr::v1::PixelSamplerSpecs& specs, int filmPixels, PixelSamplingOptions& o) const override {
    parseStage1SamplerSpec(specs.loss_grad(), "loss_grad", o, filmPixels);
  }
};

const RegisterPixelSampler kRegistered(20, std::make_unique<LossGradPixels>());

}  // namespace

}  // namespace invr
