// What a job asks of the gradients that they cannot deliver, checked once when the job is built
// (the engine then only keeps invariants). Every refusal says why and names the field, shape or
// light at fault.
#pragma once

#include <string>
#include <vector>

#include "core/diff/gradient_options.h"
#include "core/diff/parameters.h"
#include "core/scene/scene.h"

namespace invr {

// Throws InputError ("optimization.<field>: ...") for a combination of options, parameters and
// scene the gradients do not cover: shape parameters beyond direct illumination, on textured,
// glossy or smooth-shaded meshes, with pixel mini-batches or variance; moving discontinuities no
// boundary term samples (unsampledDiscontinuities) unless boundary.allow_unsampled_discontinuities;
// sampling parameters without METHOD_PT; a time-aware variance loss whose render cost depends on
// parameters it does not differentiate.
void validateGradientJob(const Scene& scene, const ParameterRegistry& params, const GradientOptions& options);

// The discontinuities that move with the job's shape or camera parameters but that no registered
// boundary term declares it samples (BoundaryTermKind::samples), one sentence each (empty: none,
// or no such parameters). Looked for in the scene as given: the moving edges, each light's
// shadows, and, which no term samples today,
//   - a moving shape (any shape, under a moving camera) touching or cutting another surface, or
//     itself, where a camera sees it (the contact curve is not a mesh edge);
//   - a spot light with a hard cone edge (cone_inner_degrees == cone_outer_degrees), whose border
//     moves across moving surfaces it lights;
//   - an image environment map seen by a moving camera (its texel borders).
std::vector<std::string> unsampledDiscontinuities(const Scene& scene, const ParameterRegistry& params);
// The same against the given term kinds instead of the registered ones.
struct BoundaryTermKind;
std::vector<std::string> unsampledDiscontinuities(const Scene& scene, const ParameterRegistry& params,
                                                  const std::vector<const BoundaryTermKind*>& terms);

}  // namespace invr
