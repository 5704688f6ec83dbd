// Unidirectional path tracing with next-event estimation (NEE+MIS or RIS) and Russian roulette.
// maxDepth = 1 is direct illumination.
#pragma once

#include "core/math/rng.h"
#include "core/render/render_options.h"
#include "core/scene/scene.h"

namespace invr {

// `primary`: the camera ray's closest hit when traced beforehand (core/render/path_walk.h).
Rgb pathRadiance(const Scene& scene, Vec3 origin, Vec3 dir, Sampler& sampler, const RenderOptions& opt,
                 PathContext* ctx = nullptr, const PrimaryHit* primary = nullptr);

}  // namespace invr
