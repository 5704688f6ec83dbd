// Renders one view into an RGB image: box pixel filter, TBB over tiles, one counter-based sample
// stream per (seed, view, pixel, sample), so the image is bit-identical for any thread count.
#pragma once

#include <functional>

#include "core/image/image.h"
#include "core/render/render_options.h"
#include "core/scene/scene.h"
#include "invr/v1/job.pb.h"

namespace invr {

struct RenderResult {
  Image image;        // width x height x 3, linear RGB
  RayStats rays;
  uint64_t nonFiniteSamples = 0;  // caught and dropped (counted here, never averaged in)
  double seconds = 0.0;
};

// progress(fraction) is called from worker threads, serialised, at most once per tile row.
RenderResult renderView(const Scene& scene, int view, const RenderOptions& opt,
                        const std::function<void(double)>& progress = {});

// First-hit auxiliary images through each pixel centre: albedo (BSDF reflectance colour), shading
// normal (world space) and ray distance (0 where the ray escapes). For denoisers and debugging.
struct Aovs {
  Image albedo, normal, depth;
};
Aovs renderAovs(const Scene& scene, int view);

// A job's render settings (validated; defaults applied for zero-valued fields, as proto3 has no
// presence for scalars).
RenderOptions renderOptionsFrom(const invr::v1::RenderSettings& settings);

}  // namespace invr
