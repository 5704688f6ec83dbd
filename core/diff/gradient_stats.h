// The engine's statistics message (proto/invr/v1/stats.proto): how the engine's counters fill it,
// the one function that sums shards, and the figures derived from it.
#pragma once

#include <cstdint>

#include "core/diff/sample_drops.h"
#include "core/render/render_options.h"
#include "invr/v1/stats.pb.h"

namespace invr {

void setRayCounts(invr::v1::GradientStats& stats, const RayStats& rays);
void setDropCounts(invr::v1::GradientStats& stats, const SampleDrops& drops);

// total += part, field by field: every number added, every map entry added key by key. Every field
// of GradientStats is a sum over shards by definition, so a field added to the message needs no
// change here.
void addGradientStats(invr::v1::GradientStats& total, const invr::v1::GradientStats& part);

// Non-finite samples dropped, wherever they were met.
uint64_t droppedSamples(const invr::v1::GradientStats& stats);
// ReSTIR's mean M and mean neighbours merged per shading point of the primal pass (0 without reuse).
double meanM(const invr::v1::GradientStats& stats);
double meanNeighbours(const invr::v1::GradientStats& stats);

}  // namespace invr
