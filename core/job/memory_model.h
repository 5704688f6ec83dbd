// Memory one worker needs for a job's largest shard: what `invr plan` prints and what the service
// checks against its per-job budget before a job is accepted.
#pragma once

#include <cstdint>

#include "core/job/problem.h"

namespace invr {

struct WorkerMemory {
  double geometry = 0;    // vertices, indices and the BVH
  double textures = 0;    // optimised textures: values, Adam moments, gradient
  double images = 0;      // targets, renders and loss gradients of the largest shard
  double reservoirs = 0;  // ReSTIR chains (current and previous) with their kd-tree
  double gradients = 0;   // per-thread gradient scratch
  double variance = 0;    // variance-aware jobs: the variance pass's images and per-thread decision records
  double boundary = 0;    // shape parameters: edge topology of every mesh and a boundary pass's candidate edges
  double total() const { return geometry + textures + images + reservoirs + gradients + variance + boundary; }
};

// `threads`: the worker's thread count (each holds a gradient scratch).
WorkerMemory estimateWorkerMemory(const Problem& problem, unsigned threads);

}  // namespace invr
