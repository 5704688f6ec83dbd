// lights/<l>/texels: an image environment map's radiance, texel by texel (width*height*3 values,
// row-major from the top row, the map's scale applied; Mitsuba <id>.data). The map is looked up
// piecewise constant, so a direction's radiance is one texel's (environmentTexel) and the
// estimators add its derivative there (path_adjoint.h). Its sampling distribution is rebuilt from
// the texels after every update and treated as detached, as Mitsuba does.
#include <limits>

#include "core/diff/parameter_kind.h"
#include "core/error.h"

namespace invr {

namespace {

class EnvironmentTexelsKind final : public ParameterKind {
 public:
  const char* name() const override { return "environment_texels"; }
  std::vector<std::string> groups() const override { return {"lights"}; }
  std::string property() const override { return "texels"; }
  std::string usage() const override { return "lights/<name>/texels"; }

  ParameterSlot bind(const Scene& scene, const ParameterName& n, const ParameterOptions&, const ParameterTables& tables,
                     const std::vector<ParameterSlot>& earlier) const override {
    if (n.parts.size() != 3) failParameter(n.given, "expected " + usage());
    const int l = namedLight(scene, n);
    const Light& light = scene.lights[size_t(l)];
    if (light.kind != LightKind::Environment)
      failParameter(n.given, "light '" + n.parts[1] + "' is not an image environment map: its value is lights/" + n.parts[1] + "/intensity");
    if (!(light.scale > 0.f))
      failParameter(n.given, "the environment's scale is " + std::to_string(light.scale) + ", so its texels cannot be recovered");
    ParameterSlot slot;
    slot.light = l;
    slot.channels = 3;
    slot.width = light.envImage->width();
    slot.height = light.envImage->height();
    slot.size = uint32_t(3 * slot.width * slot.height);
    slot.lower = kPositiveFloor;
    slot.upper = std::numeric_limits<float>::infinity();
    refuseSameValue(n, ParameterTables::lookup(tables.texels, l), earlier);
    return slot;
  }
  void attach(const Scene&, const ParameterSlot& slot, ParameterTables& tables) const override {
    ParameterTables::put(tables.texels, size_t(slot.light), int(slot.offset));
  }
  void read(const Scene& scene, const ParameterSlot& s, const ParameterTables&, float* out) const override {
    const Light& l = scene.lights[size_t(s.light)];
    const Image& im = *l.envImage;
    for (int y = 0; y < s.height; ++y)
      for (int x = 0; x < s.width; ++x) {
        const Rgb v = im.rgb(x, y) * l.scale;
        for (int c = 0; c < 3; ++c) out[3 * (y * s.width + x) + c] = v[c];
      }
  }
  void write(const float* in, const ParameterSlot& s, const ParameterTables&, Scene& scene, bool refreshSampling,
             SceneChanges& changes) const override {
    Light& l = scene.lights[size_t(s.light)];
    if (l.envImage->channels() < 3) l.envImage = std::make_shared<Image>(s.width, s.height, 3);  // a grey map turns colour
    Image& im = *l.envImage;
    const float inv = 1.f / l.scale;
    for (int y = 0; y < s.height; ++y)
      for (int x = 0; x < s.width; ++x) {
        const float* t = in + 3 * (y * s.width + x);
        im.setRgb(x, y, Rgb(t[0], t[1], t[2]) * inv);
      }
    // The map is sampled by its texels' luminance: rebuilt here, and detached from the derivative
    // (an estimator's expectation does not depend on its sampling density).
    if (refreshSampling) buildEnvironmentDistribution(l);
    changes.emission = true;
  }
  void offer(const Scene& scene, std::vector<OfferedName>& out) const override {
    for (size_t l = 0; l < scene.lights.size(); ++l) out.push_back({"lights/" + scene.lights[l].name + "/texels", {scene.lights[l].name + ".data"}, int(l)});
  }
  // An envmap's bitmap: <emitter id>.data.
  std::string fromMitsuba(const Scene& scene, const std::vector<std::string>& owner, const std::string& prop, bool data) const override {
    if (!data || !prop.empty() || owner.size() != 1 || lightIndex(scene, owner[0]) < 0) return "";
    return "lights/" + owner[0] + "/texels";
  }
  std::string mitsubaProperties() const override { return "data of an envmap"; }
  bool zeroBiasesReuse() const override { return true; }
  // The variance visitor scores each light's value as one number per channel; each texel would
  // need its own.
  bool varianceDerivatives() const override { return false; }
};

const RegisterParameterKind kEnvironmentTexels(21, std::make_unique<EnvironmentTexelsKind>());

}  // namespace

}  // namespace invr
