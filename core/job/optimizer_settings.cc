#include "core/job/optimizer_settings.h"

#include "core/error.h"

namespace invr {

OptimizerKind optimizerKindFromName(const std::string& name) {
  if (name == "adam") return OptimizerKind::Adam;
  if (name == "sgd") return OptimizerKind::Sgd;
  throw InputError("unknown optimizer '" + name + "' (use adam or sgd)");
}

const char* optimizerKindName(OptimizerKind kind) { return kind == OptimizerKind::Adam ? "adam" : "sgd"; }

}  // namespace invr
