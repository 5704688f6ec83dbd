// Image losses and their adjoints dL/dI. The loss of a view is the mean over pixels and channels;
// a mini-batch loss is the mean over its views.
//   l2:           (I - T)^2
//   relative_l2:  (I - T)^2 / (T^2 + 0.01)   (denominator from the target: a constant in I)
//   l1:           |I - T|   (its adjoint sign(I - T) is biased when I is a noisy estimate)
#pragma once

#include <string>
#include <vector>

#include "core/image/image.h"

namespace invr {

enum class LossKind { L2, RelativeL2, L1 };

LossKind lossKindFromName(const std::string& name);  // throws InputError
const char* lossName(LossKind kind);

// Loss of `rendered` against `target` (same size, 3 channels). If adjoint is non-null it receives
// dLoss/dI per pixel and channel (already divided by the pixel and channel count, and by
// viewsInBatch so mini-batch means come out right).
// With pixelWeights (one per pixel, e.g. count / (N p) of a pixel mini-batch), pixels of weight 0
// are skipped and the others weighted: an unbiased estimate of the full loss and its adjoint.
double imageLoss(LossKind kind, const Image& rendered, const Image& target, Image* adjoint, int viewsInBatch = 1,
                 const std::vector<float>* pixelWeights = nullptr);

// An unbiased estimate of the loss of the expected image E[I] from two independent renders of it:
// l2 (I1 - T)(I2 - T), relative_l2 the same weighted, since E[(I1 - T)(I2 - T)] = (E[I] - T)^2.
// (One render's (I - T)^2 adds Var(I), which would favour whichever method is less noisy rather
// than closer.) l1 has no such estimate: |(I1 + I2)/2 - T|, biased upwards by the noise.
// Normalised and weighted like imageLoss.
double unbiasedImageLoss(LossKind kind, const Image& render1, const Image& render2, const Image& target, int viewsInBatch = 1,
                         const std::vector<float>* pixelWeights = nullptr);

}  // namespace invr
