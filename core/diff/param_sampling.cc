// Sampling parameters (Yan et al. 2024; they change a render's noise, never its mean):
//   sampling/light_logits               one logit per light: NEE picks lights by their softmax
//   sampling/pixel_light_logits/<view>  per cell of a map over view <view>'s film: one logit per light
//   sampling/rr_survival                Russian-roulette survival of bounce 1, 2, ... (fixed survival)
// Logits start at log(the current selection pmf): today's selection by power.
#include <algorithm>
#include <cmath>
#include <cstdlib>

#include "core/diff/parameter_kind.h"
#include "core/error.h"

namespace invr {

namespace {

class SamplingKind : public ParameterKind {
 public:
  std::vector<std::string> groups() const override { return {"sampling"}; }
  bool changesNoiseOnly() const override { return true; }

 protected:
  // The pmf logits start from: the scene's selection now (log pmf, floored at the lower bound).
  static void currentLogits(const Scene& scene, float lower, float* dst) {
    for (size_t i = 0; i < scene.lights.size(); ++i) {
      const float p = scene.lightSelection().pmf(i);
      dst[i] = p > 0.f ? std::max(std::log(p), lower) : lower;
    }
  }
  static void needTwoLights(const Scene& scene, const std::string& given) {
    if (scene.lights.size() < 2)
      failParameter(given, "light selection needs at least two lights (the scene has " + std::to_string(scene.lights.size()) + ")");
  }
  static void logitDefaults(ParameterSlot& slot) {
    slot.channels = 1;
    slot.lower = -20.f;
    slot.upper = 20.f;
    slot.learningRate = 0.1f;
  }
};

class LightLogitsKind final : public SamplingKind {
 public:
  const char* name() const override { return "light_logits"; }
  std::string property() const override { return "light_logits"; }
  std::string usage() const override { return "sampling/light_logits"; }
  ParameterSlot bind(const Scene& scene, const ParameterName& n, const ParameterOptions&, const ParameterTables& tables,
                     const std::vector<ParameterSlot>&) const override {
    if (n.parts.size() != 2) failParameter(n.given, "expected " + usage());
    needTwoLights(scene, n.given);
    if (tables.lightLogits >= 0) failParameter(n.given, "listed twice");
    ParameterSlot slot;
    logitDefaults(slot);
    slot.size = uint32_t(scene.lights.size());
    return slot;
  }
  void attach(const Scene&, const ParameterSlot& slot, ParameterTables& tables) const override { tables.lightLogits = int(slot.offset); }
  void read(const Scene& scene, const ParameterSlot& s, const ParameterTables&, float* out) const override {
    if (scene.sampling.lightLogits.size() == s.size) std::copy(scene.sampling.lightLogits.begin(), scene.sampling.lightLogits.end(), out);
    else currentLogits(scene, s.lower, out);
  }
  void write(const float* in, const ParameterSlot& s, const ParameterTables&, Scene& scene, bool, SceneChanges& changes) const override {
    scene.sampling.lightLogits.assign(in, in + s.size);
    changes.selection = true;
  }
  void offer(const Scene&, std::vector<OfferedName>& out) const override { out.push_back({"sampling/light_logits", {}, 0}); }
};

class PixelLightLogitsKind final : public SamplingKind {
 public:
  const char* name() const override { return "pixel_light_logits"; }
  std::string property() const override { return "pixel_light_logits"; }
  std::string usage() const override { return "sampling/pixel_light_logits/<view>"; }
  ParameterSlot bind(const Scene& scene, const ParameterName& n, const ParameterOptions& o, const ParameterTables& tables,
                     const std::vector<ParameterSlot>&) const override {
    if (n.parts.size() != 3) failParameter(n.given, "expected " + usage());
    needTwoLights(scene, n.given);
    const std::string& v = n.parts[2];
    char* end = nullptr;
    const long view = std::strtol(v.c_str(), &end, 10);
    if (v.empty() || *end != '\0' || view < 0 || view >= long(scene.cameras.size()))
      failParameter(n.given, "view '" + v + "' is not a view index (the scene has " + std::to_string(scene.cameras.size()) + " views, 0.." +
                                 std::to_string(int(scene.cameras.size()) - 1) + ")");
    if (ParameterTables::lookup(tables.pixelLogits, int(view)) >= 0) failParameter(n.given, "listed twice");
    const int w = o.mapWidth > 0 ? o.mapWidth : scene.width, h = o.mapHeight > 0 ? o.mapHeight : scene.height;
    if (w > scene.width || h > scene.height || o.mapWidth < 0 || o.mapHeight < 0)
      failParameter(n.given, "map resolution " + std::to_string(w) + "x" + std::to_string(h) + " must be positive and at most the film's (" +
                                 std::to_string(scene.width) + "x" + std::to_string(scene.height) + ")");
    ParameterSlot slot;
    logitDefaults(slot);
    slot.view = int(view);
    slot.width = w;
    slot.height = h;
    slot.channels = int(scene.lights.size());
    slot.size = uint32_t(w * h) * uint32_t(scene.lights.size());
    return slot;
  }
  // The slot's index is the registry's next one: the kinds attach before the slot is appended.
  void attach(const Scene&, const ParameterSlot& slot, ParameterTables& tables) const override {
    ParameterTables::put(tables.pixelLogits, size_t(slot.view), tables.nextSlot);
  }
  void read(const Scene& scene, const ParameterSlot& s, const ParameterTables&, float* out) const override {
    const auto* map = size_t(s.view) < scene.sampling.pixelLogits.size() ? &scene.sampling.pixelLogits[size_t(s.view)] : nullptr;
    if (map && map->logits.size() == s.size) std::copy(map->logits.begin(), map->logits.end(), out);
    else
      for (int c = 0; c < s.width * s.height; ++c) currentLogits(scene, s.lower, out + size_t(c) * size_t(s.channels));
  }
  void write(const float* in, const ParameterSlot& s, const ParameterTables&, Scene& scene, bool, SceneChanges&) const override {
    if (scene.sampling.pixelLogits.size() <= size_t(s.view)) scene.sampling.pixelLogits.resize(size_t(s.view) + 1);
    auto& map = scene.sampling.pixelLogits[size_t(s.view)];
    map.width = s.width;
    map.height = s.height;
    map.logits.assign(in, in + s.size);
  }
  void offer(const Scene& scene, std::vector<OfferedName>& out) const override {
    for (size_t v = 0; v < scene.cameras.size(); ++v) out.push_back({"sampling/pixel_light_logits/" + std::to_string(v), {}, 0});
  }
};

class SurvivalKind final : public SamplingKind {
 public:
  const char* name() const override { return "rr_survival"; }
  std::string property() const override { return "rr_survival"; }
  std::string usage() const override { return "sampling/rr_survival"; }
  ParameterSlot bind(const Scene& scene, const ParameterName& n, const ParameterOptions&, const ParameterTables& tables,
                     const std::vector<ParameterSlot>&) const override {
    if (n.parts.size() != 2) failParameter(n.given, "expected " + usage());
    if (scene.sampling.survival.empty())
      failParameter(n.given, "needs fixed-survival Russian roulette (render.russian_roulette \"fixed\"; a job naming this parameter gets it)");
    if (tables.survival >= 0) failParameter(n.given, "listed twice");
    ParameterSlot slot;
    slot.channels = 1;
    slot.size = uint32_t(scene.sampling.survival.size());
    slot.lower = 0.05f;
    slot.upper = 1.f;
    slot.learningRate = 0.02f;
    return slot;
  }
  void attach(const Scene&, const ParameterSlot& slot, ParameterTables& tables) const override { tables.survival = int(slot.offset); }
  void read(const Scene& scene, const ParameterSlot&, const ParameterTables&, float* out) const override {
    std::copy(scene.sampling.survival.begin(), scene.sampling.survival.end(), out);
  }
  void write(const float* in, const ParameterSlot& s, const ParameterTables&, Scene& scene, bool, SceneChanges&) const override {
    scene.sampling.survival.assign(in, in + s.size);
  }
  void offer(const Scene&, std::vector<OfferedName>& out) const override { out.push_back({"sampling/rr_survival", {}, 0}); }
};

const RegisterParameterKind kLightLogits(40, std::make_unique<LightLogitsKind>());
const RegisterParameterKind kPixelLightLogits(41, std::make_unique<PixelLightLogitsKind>());
const RegisterParameterKind kSurvival(42, std::make_unique<SurvivalKind>());

}  // namespace

}  // namespace invr
