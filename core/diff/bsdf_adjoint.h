// Backpropagation into a material's parameters: given the adjoint of a BSDF value at a surface
// point (dL/d(f|cos|), per channel) and the BSDF's derivatives there, adds the albedo and
// roughness gradients (constant, or the bilinear texels under uv) to the path's gradient.
// Shared by the direct-illumination estimators and path replay.
#pragma once

#include "core/bsdf/bsdf.h"
#include "core/diff/gradient_sink.h"
#include "core/diff/parameters.h"
#include "core/scene/scene.h"

namespace invr {

// Whether the material has parameters at all (so callers can skip evaluating derivatives).
inline bool hasBsdfParameters(const ParameterRegistry& params, int material) {
  return material >= 0 && (params.albedoOffset(material) >= 0 || params.roughnessOffset(material) >= 0);
}

inline void addBsdfGradient(const ParameterRegistry& params, const Scene& scene, int material, Vec2 uv, const BsdfDerivatives& dd,
                            Rgb adjEval, PathGradient& grad) {
  if (material < 0) return;
  int aOff = params.albedoOffset(material), rOff = params.roughnessOffset(material);
  if (aOff < 0 && rOff < 0) return;
  const Material& mat = scene.materials[size_t(material)];
  if (aOff >= 0) {
    Rgb g = adjEval * dd.dAlbedo;
    if (mat.albedo.isConstant()) {
      for (int c = 0; c < 3; ++c) grad.add(uint32_t(aOff + c), g[c]);
    } else {
      int tw = mat.albedo.image()->width();
      mat.albedo.forEachTexel(uv, [&](int tx, int ty, float w) {
        for (int c = 0; c < 3; ++c) grad.add(uint32_t(aOff + (ty * tw + tx) * 3 + c), g[c] * w);
      });
    }
  }
  if (rOff >= 0 && mat.roughness.evalScalar(uv) > kMinAlpha) {
    float g = adjEval.x * dd.dAlpha.x + adjEval.y * dd.dAlpha.y + adjEval.z * dd.dAlpha.z;
    if (mat.roughness.isConstant()) {
      grad.add(uint32_t(rOff), g);
    } else {
      int tw = mat.roughness.image()->width();
      mat.roughness.forEachTexel(uv, [&](int tx, int ty, float w) { grad.add(uint32_t(rOff + ty * tw + tx), g * w); });
    }
  }
}

}  // namespace invr
