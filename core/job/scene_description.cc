#include "core/job/scene_description.h"

#include "core/diff/parameter_catalog.h"
#include "core/math/decimal.h"

namespace invr {


invr::v1::SceneDescription describeScene(const Scene& scene) {
  invr::v1::SceneDescription desc;
  for (const ParameterInfo& p : optimisableParameters(scene)) {
    invr::v1::ParameterInfo* o = desc.add_parameters();
    o->set_name(p.name);
    o->set_kind(p.kind);
    o->set_size(p.size);
    o->set_width(uint32_t(p.width));
    o->set_height(uint32_t(p.height));
    o->set_channels(uint32_t(p.channels));
    o->set_lower(shortestDecimal(p.lower));
    o->set_upper(shortestDecimal(p.upper));
    o->set_learning_rate(shortestDecimal(p.learningRate));
    for (const auto& a : p.aliases) o->add_aliases(a);
  }
  return desc;
}

}  // namespace invr
