// Multi-bounce path tracing (NEE + MIS at every vertex, Russian roulette) and its derivative for
// material and light parameters by path replay backpropagation (Vicini et al. 2021): a first
// pass computes the path's radiance L; a second pass replays the same path from the same random
// numbers and, at each vertex, backpropagates the adjoint through
//   - the light sample there:       d(f|cos|)(wo, wl) * weight * Le, and d Le,
//   - emission reached there:       d Le,
//   - the continuation:             d(f|cos|)(wo, wi) * (L - radiance gathered so far) / (f|cos|)(wo, wi),
// because everything gathered after the vertex carries its f|cos|/pdf factor once. Pdfs, MIS and
// roulette weights are detached, as in the direct-illumination estimators. Memory is constant
// and time linear in the path length.
#pragma once

#include "core/diff/gradient_sink.h"
#include "core/diff/parameters.h"
#include "core/render/render_options.h"
#include "core/scene/scene.h"

namespace invr {

struct PathReplaySettings {
  int maxDepth = 4;            // path vertices after the camera
  int russianRouletteDepth = 3;
};

// The radiance along the camera ray (o, d). `sampler` is taken by value: pass the same state to
// pathReplayBackprop to replay the same path.
Rgb pathReplayRadiance(const Scene& scene, Vec3 o, Vec3 d, Sampler sampler, const PathReplaySettings& s, RayStats* rays = nullptr);

// Adds adjoint * dL/dtheta of that same path to `grad`, given its radiance L (from the first pass).
void pathReplayBackprop(const Scene& scene, const ParameterRegistry& params, Vec3 o, Vec3 d, Sampler sampler,
                        const PathReplaySettings& s, Rgb L, Rgb adjoint, PathGradient& grad, RayStats* rays = nullptr);

}  // namespace invr
