#include "core/diff/pixel_sampler.h"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "core/error.h"

namespace invr {

namespace {

void checkPixelSamples(int samples, int filmPixels, const std::string& field) {
  if (samples < 0 || samples > 16 * filmPixels)
    throw InputError("optimization." + field + ": must be in 1.." + std::to_string(16 * filmPixels) + " (got " + std::to_string(samples) + ")");
}

class AllPixels final : public PixelSampler {
 public:
  const char* name() const override { return "all"; }
  bool miniBatch() const override { return false; }
  std::string describe(const PixelSamplingOptions&) const override { return "every pixel, every step"; }
};

class UniformPixels final : public PixelSampler {
 public:
  const char* name() const override { return "uniform"; }
  std::string describe(const PixelSamplingOptions&) const override { return "p_j = 1 / P"; }
  void parseOptions(const invr::v1::PixelSamplerSpecs& specs, int filmPixels, PixelSamplingOptions& o) const override {
    checkPixelSamples(specs.uniform().samples(), filmPixels, "pixel_samplers.uniform.samples");
    if (specs.uniform().samples() > 0) o.samplesPerView = specs.uniform().samples();
  }
};

struct Registry {
  std::vector<std::pair<int, std::unique_ptr<PixelSampler>>> owned;
  std::vector<const PixelSampler*> ordered;
  void add(int order, std::unique_ptr<PixelSampler> s) {
    for (const auto& [o, k] : owned)
      if (std::string(k->name()) == s->name()) throw std::logic_error(std::string("pixel sampler '") + s->name() + "' registered twice");
    owned.emplace_back(order, std::move(s));
    std::stable_sort(owned.begin(), owned.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
    ordered.clear();
    for (const auto& [o, k] : owned) ordered.push_back(k.get());
  }
};

// The samplers without maps are here, so they exist before any file's registration runs.
Registry& registry() {
  static Registry r = [] {
    Registry x;
    x.add(0, std::make_unique<AllPixels>());
    x.add(10, std::make_unique<UniformPixels>());
    return x;
  }();
  return r;
}

}  // namespace

RegisterPixelSampler::RegisterPixelSampler(int order, std::unique_ptr<PixelSampler> sampler) { registry().add(order, std::move(sampler)); }

const std::vector<const PixelSampler*>& pixelSamplers() { return registry().ordered; }

const PixelSampler& pixelSampler(const std::string& name) {
  std::string names;
  for (const PixelSampler* s : pixelSamplers()) {
    if (name == s->name()) return *s;
    names += std::string(names.empty() ? "" : ", ") + s->name();
  }
  throw InputError("unknown pixel sampler '" + name + "' (use " + names + ")");
}

PixelSamplingOptions parsePixelSamplingOptions(const invr::v1::OptimizationSpec& o, int filmPixels) {
  auto fail = [](const std::string& field, const std::string& why) { throw InputError("optimization." + field + ": " + why); };
  const PixelSamplingOptions defaults;
  PixelSamplingOptions p;
  try {
    p.sampler = &pixelSampler(o.pixel_sampler().empty() ? defaults.sampler->name() : o.pixel_sampler());
  } catch (const InputError& e) {
    fail("pixel_sampler", e.what());
  }
  checkPixelSamples(o.pixel_samples(), filmPixels, "pixel_samples");
  p.samplesPerView = o.pixel_samples();
  if (!(o.pixel_defensive() >= 0 && o.pixel_defensive() <= 1))
    fail("pixel_defensive", "must be in (0, 1]: every pixel needs a probability above zero");
  p.defensive = o.pixel_defensive() > 0 ? float(o.pixel_defensive()) : defaults.defensive;
  if (o.pixel_refresh() < 0 || o.pixel_refresh() > 100000) fail("pixel_refresh", "must be in 1..100000 (got " + std::to_string(o.pixel_refresh()) + ")");
  p.refreshEvery = o.pixel_refresh() > 0 ? o.pixel_refresh() : defaults.refreshEvery;
  // Options of a sampler the job does not use would be silently ignored: refuse them.
  const auto& specs = o.pixel_samplers();
  std::vector<const google::protobuf::FieldDescriptor*> set;
  specs.GetReflection()->ListFields(specs, &set);
  for (const google::protobuf::FieldDescriptor* f : set)
    if (f->name() != p.sampler->name())
      fail("pixel_samplers." + f->name(), std::string("options of a sampler the job does not use (pixel_sampler is '") + p.sampler->name() + "')");
  p.sampler->parseOptions(specs, filmPixels, p);
  return p;
}

template <class Spec>
void parseStage1SamplerSpec(const Spec& spec, const std::string& field, PixelSamplingOptions& o, int filmPixels) {
  const std::string at = "pixel_samplers." + field + ".";
  auto fail = [&](const std::string& name, const std::string& why) { throw InputError("optimization." + at + name + ": " + why); };
  checkPixelSamples(spec.samples(), filmPixels, at + "samples");
  if (spec.samples() > 0) o.samplesPerView = spec.samples();
  if (!(spec.defensive() >= 0 && spec.defensive() <= 1)) fail("defensive", "must be in (0, 1]: every pixel needs a probability above zero");
  if (spec.defensive() > 0) o.defensive = float(spec.defensive());
  if (spec.refresh() < 0 || spec.refresh() > 100000) fail("refresh", "must be in 1..100000 (got " + std::to_string(spec.refresh()) + ")");
  if (spec.refresh() > 0) o.refreshEvery = spec.refresh();
  if (spec.stage1_stride() < 0 || spec.stage1_stride() > 16) fail("stage1_stride", "must be in 1..16 (got " + std::to_string(spec.stage1_stride()) + ")");
  if (spec.stage1_stride() > 0) o.stage1Stride = spec.stage1_stride();
  if (spec.stage1_history() < 0 || spec.stage1_history() > 1024)
    fail("stage1_history", "must be in 1..1024 (got " + std::to_string(spec.stage1_history()) + ")");
  if (spec.stage1_history() > 0) o.stage1History = spec.stage1_history();
}

template void parseStage1SamplerSpec(const invr::v1::LossGradPixelsSpec&, const std::string&, PixelSamplingOptions&, int);
template void parseStage1SamplerSpec(const invr::v1::AdaptivePixelsSpec&, const std::string&, PixelSamplingOptions&, int);

std::vector<float> upsampleEdgeAware(const Stage1& s, const std::vector<float>& cells) {
  const int W = s.width, H = s.height;
  auto cellOf = [&](int x, int y) {
    int i = std::min(s.gw - 1, x / s.stride), j = std::min(s.gh - 1, y / s.stride);
    return size_t(j * s.gw + i);
  };
  std::vector<float> up(size_t(W) * size_t(H));
  for (int y = 0; y < H; ++y)
    for (int x = 0; x < W; ++x) up[size_t(y * W + x)] = cells[cellOf(x, y)];
  if (s.guide.empty()) return up;
  // Cross-bilateral: neighbours count in proportion to how alike their normal and albedo are,
  // so probability mass does not bleed across object and texture edges.
  std::vector<float> out(up.size());
  constexpr int R = 2;
  constexpr float kSpatial = 1.f / (2.f * 1.5f * 1.5f), kGuide = 1.f / (2.f * 0.1f * 0.1f);
  float spatial[2 * R + 1][2 * R + 1];
  for (int dy = -R; dy <= R; ++dy)
    for (int dx = -R; dx <= R; ++dx) spatial[dy + R][dx + R] = std::exp(-float(dx * dx + dy * dy) * kSpatial);
  // Rows in parallel: each output pixel is written once, so the result does not depend on threads.
  tbb::parallel_for(0, H, [&](int y) {
    for (int x = 0; x < W; ++x) {
      const float* g0 = &s.guide[size_t(y * W + x) * 6];
      double sum = 0, wsum = 0;
      for (int dy = -R; dy <= R; ++dy)
        for (int dx = -R; dx <= R; ++dx) {
          int xx = x + dx, yy = y + dy;
          if (xx < 0 || yy < 0 || xx >= W || yy >= H) continue;
          const float* g1 = &s.guide[size_t(yy * W + xx) * 6];
          float dg = 0;
          for (int k = 0; k < 6; ++k) dg += (g0[k] - g1[k]) * (g0[k] - g1[k]);
          // Guide weight exp(-dg k) by a rational stand-in: as edge-preserving, a fraction of the cost.
          float w = spatial[dy + R][dx + R] / (1.f + dg * kGuide * (1.f + 0.5f * dg * kGuide));
          sum += double(w) * double(up[size_t(yy * W + xx)]);
          wsum += double(w);
        }
      out[size_t(y * W + x)] = float(sum / wsum);
    }
  });
  return out;
}

std::vector<float> defensiveMixture(const std::vector<float>& map, float defensive, uint64_t* nonFinite) {
  const size_t n = map.size();
  double total = 0;
  for (float v : map) {
    if (std::isfinite(v) && v > 0.f) total += double(v);
    if (!std::isfinite(v) && nonFinite) ++*nonFinite;
  }
  std::vector<float> p(n);
  const double uniform = 1.0 / double(n);
  if (!(total > 0.0)) {
    std::fill(p.begin(), p.end(), float(uniform));
    return p;
  }
  for (size_t i = 0; i < n; ++i) {
    double v = std::isfinite(map[i]) && map[i] > 0.f ? double(map[i]) / total : 0.0;
    p[i] = float((1.0 - double(defensive)) * v + double(defensive) * uniform);
  }
  return p;
}

std::string stage1HistoryNote(const PixelSamplingOptions& o) {
  return o.stage1History > 1 ? ", maps from the last " + std::to_string(o.stage1History) + " stage-1 passes" : "";
}

void accumulateStage1(Stage1& history, const Stage1& fresh, int window) {
  const bool sameGrid = history.passes > 0 && history.gw == fresh.gw && history.gh == fresh.gh && history.stride == fresh.stride &&
                        history.width == fresh.width && history.height == fresh.height;
  if (!sameGrid || window <= 1) {
    history = fresh;
    return;
  }
  // Weight of the newest pass: 1/n while the history holds fewer than `window`, then 1/window.
  const int n = std::min(history.passes + fresh.passes, window);
  const float w = float(fresh.passes) / float(n);
  auto blend = [w](std::vector<float>& into, const std::vector<float>& from) {
    for (size_t i = 0; i < into.size(); ++i) into[i] += w * (from[i] - into[i]);
  };
  blend(history.adjointAbs, fresh.adjointAbs);
  blend(history.adjointSq, fresh.adjointSq);
  blend(history.derivSq, fresh.derivSq);
  history.guide = fresh.guide;
  history.passes = n;
}

PixelMap buildPixelMap(const PixelSamplingOptions& o, const Stage1& s, uint64_t step, SampleDrops* drops) {
  PixelMap m;
  uint64_t* nonFinite = drops ? &drops->pixelMap : nullptr;
  m.computedAt = step;
  const size_t n = size_t(s.width) * size_t(s.height);
  if (o.sampler->usesStage1())
    m.setProbabilities(defensiveMixture(upsampleEdgeAware(s, o.sampler->cellValues(s, o)), o.defensive, nonFinite));
  else
    m.setProbabilities(std::vector<float>(n, float(1.0 / double(n))));
  return m;
}

PixelBatch drawPixelBatch(const PixelMap& map, int n, RngKey key) {
  const Distribution1D& dist = map.dist;
  PixelBatch b;
  b.weight.assign(map.p.size(), 0.f);
  b.draws.assign(map.p.size(), 0);
  Sampler sampler(key);
  for (int i = 0; i < n; ++i) {
    size_t j = dist.sample(sampler.next1D());
    ++b.draws[j];
    // The distribution normalises p itself; use its pmf so the weights match what was drawn.
    b.weight[j] += 1.f / (float(n) * dist.pmf(j));
  }
  return b;
}

}  // namespace invr
