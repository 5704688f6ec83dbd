#include "core/job/optimizer_settings.h"

#include "core/error.h"

namespace invr {

OptimizerKind optimizerKindFromName(const std::string& name) {
  if (name == "adam") return OptimizerKind::Adam;
  if (name == "sgd") return OptimizerKind::Sgd;
  if (name == "adam_uniform") return OptimizerKind::AdamUniform;
  throw InputError("unknown optimizer '" + name + "' (use adam, adam_uniform or sgd)");
}

const char* optimizerKindName(OptimizerKind kind) {
  switch (kind) {
    case OptimizerKind::Adam: return "adam";
    case OptimizerKind::AdamUniform: return "adam_uniform";
    default: return "sgd";
  }
}

}  // namespace invr
