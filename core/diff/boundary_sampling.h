// What the boundary estimators (primary_boundary.h, delta_shadow_boundary.h) share: the radiance
// jump across a curve on the film, measured by one camera sample on each side, and the loop that
// runs a pass's samples over threads with the same sums for any thread count.
#pragma once

#include <atomic>
#include <functional>
#include <vector>

#include "core/diff/boundary_term.h"
#include "core/diff/film_projection.h"
#include "core/diff/interior_estimator.h"
#include "core/diff/pass_driver.h"

namespace invr {


struct FilmCrossing {
  int px = 0, py = 0;  // the pixel of the crossing point
  Rgb jump;            // L(x - eps n) - L(x + eps n)
};

// Traces one camera sample of `estimator` on each side of film point x, eps pixels along the unit
// film normal n, both sides with the same random numbers (one fork of `sampler`): each side is
// still an unbiased estimate, and where the two sides see nearly the same thing (a crease between
// nearly coplanar facets) their light-sampling noise cancels in the difference instead of adding.
// With a fork per side, the crease samples of a fine flat mesh (82K triangles) carried jumps of
// 0.2-1 where the true jump is ~0.01, and the primary term's noise was ~35x the whole gradient
// (docs/shapes.md, "A fine mesh's pose"). ReSTIR reads x's pixel's reservoirs.
FilmCrossing radianceJump(const Scene& scene, const InteriorEstimator& estimator, const Camera& cam, FilmPoint x, Vec2 n, double eps,
                          const Sampler& sampler, SampleCounters& counters);

// Runs samples 0 .. samples-1 in fixed chunks on the thread pool. body(i, counters, grad) adds
// sample i's derivatives to grad, and sets the pixel whose dL/dI it read (grad.setPixel); a sample
// with a non-finite entry is dropped and counted. Chunks are reduced in order into `gradient`, and
// into `pixels` when a derivative image is asked for. Throws EvaluationCancelled when `cancel` is
// raised.
void runBoundarySamples(int samples, GradientScratchPool& scratch, std::vector<double>& gradient, const std::atomic<bool>* cancel,
                        BoundaryPassStats& stats, const std::function<void(int, SampleCounters&, PathGradient&)>& body,
                        PixelDerivativeSink* pixels = nullptr);

}  // namespace invr
