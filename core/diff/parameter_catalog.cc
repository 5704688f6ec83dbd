#include "core/diff/parameter_catalog.h"

#include <algorithm>

#include "core/diff/parameters.h"
#include "core/error.h"

namespace invr {

namespace {

const char* kindName(ParamKind k) {
  switch (k) {
    case ParamKind::Albedo: return "albedo";
    case ParamKind::Roughness: return "roughness";
    case ParamKind::LightIntensity: return "light_intensity";
    case ParamKind::EnvironmentTexels: return "environment_texels";
    case ParamKind::LightLogits: return "light_logits";
    case ParamKind::PixelLightLogits: return "pixel_light_logits";
    case ParamKind::Survival: return "rr_survival";
    case ParamKind::ShapeTranslation: return "translation";
    case ParamKind::ShapeRotation: return "rotation";
    case ParamKind::ShapeScale: return "scale";
    case ParamKind::ShapeVertices: return "vertices";
  }
  return "unknown";
}

// The Mitsuba names that resolve to `name` in this scene (checked through the same mapping a job's
// names go through, so none is listed that would not be accepted).
std::vector<std::string> aliasesOf(const Scene& scene, const std::string& name, const std::vector<std::string>& candidates) {
  std::vector<std::string> out;
  for (const auto& c : candidates) {
    try {
      if (invrParameterName(scene, c) == name && std::find(out.begin(), out.end(), c) == out.end()) out.push_back(c);
    } catch (const InputError&) {
    }
  }
  return out;
}

}  // namespace

std::vector<ParameterInfo> optimisableParameters(const Scene& scene) {
  std::vector<std::pair<std::string, std::vector<std::string>>> names;  // invr name, Mitsuba candidates
  for (const auto& m : scene.materials) {
    std::vector<std::string> ids = m.aliases;
    ids.insert(ids.begin(), m.name);
    std::vector<std::string> albedo, alpha;
    for (const auto& id : ids) {
      albedo.push_back(id + ".reflectance.value");
      albedo.push_back(id + ".reflectance.data");
      alpha.push_back(id + ".alpha.value");
    }
    names.push_back({"materials/" + m.name + "/albedo", albedo});
    names.push_back({"materials/" + m.name + "/roughness", alpha});
  }
  for (size_t l = 0; l < scene.lights.size(); ++l) {
    const std::string& n = scene.lights[l].name;
    std::vector<std::string> mi = {n + ".radiance.value", n + ".intensity.value"};
    for (size_t s = 0; s < scene.meshLight.size(); ++s)
      if (scene.meshLight[s] == int(l)) mi.push_back(scene.meshNames[s] + ".emitter.radiance.value");
    names.push_back({"lights/" + n + "/intensity", mi});
    names.push_back({"lights/" + n + "/texels", {n + ".data"}});
  }
  for (const auto& s : scene.meshNames)
    for (const char* p : {"translation", "rotation", "scale", "vertices"})
      names.push_back({"shapes/" + s + "/" + p, std::string(p) == "vertices" ? std::vector<std::string>{s + ".vertex_positions"} : std::vector<std::string>{}});
  for (const auto& g : scene.groups)
    for (const char* p : {"translation", "rotation", "scale"}) names.push_back({"groups/" + g.name + "/" + p, {}});
  names.push_back({"sampling/light_logits", {}});
  for (size_t v = 0; v < scene.cameras.size(); ++v) names.push_back({"sampling/pixel_light_logits/" + std::to_string(v), {}});
  names.push_back({"sampling/rr_survival", {}});

  std::vector<ParameterInfo> out;
  for (const auto& [name, mitsuba] : names) {
    ParameterRegistry reg;  // one per name: each is asked about on its own
    try {
      const ParameterSlot& s = reg.add(scene, name);
      ParameterInfo info;
      info.name = name;
      info.kind = kindName(s.kind);
      info.size = s.size;
      info.width = s.width;
      info.height = s.height;
      info.channels = s.kind == ParamKind::ShapeVertices || s.kind == ParamKind::ShapeTranslation || s.kind == ParamKind::ShapeRotation ||
                              s.kind == ParamKind::ShapeScale
                          ? (s.component >= 0 ? 1 : 3)
                          : s.channels;
      info.lower = s.lower;
      info.upper = s.upper;
      info.learningRate = s.learningRate;
      // A texture is Mitsuba's bitmap (.data), a constant its .value.
      std::vector<std::string> forms;
      for (const auto& m : mitsuba) {
        const bool data = m.size() > 5 && m.compare(m.size() - 5, 5, ".data") == 0;
        if (m.size() <= 6 || m.compare(m.size() - 6, 6, ".value") != 0 ? (!data || s.width > 0) : s.width == 0) forms.push_back(m);
      }
      info.aliases = aliasesOf(scene, name, forms);
      out.push_back(std::move(info));
    } catch (const InputError&) {
      // not optimisable in this scene (no roughness, a single light, ...)
    }
  }
  return out;
}

}  // namespace invr
