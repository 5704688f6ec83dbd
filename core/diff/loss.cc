#include "core/diff/loss.h"

#include <cmath>

#include "core/error.h"

namespace invr {

LossKind lossKindFromName(const std::string& name) {
  if (name == "l2") return LossKind::L2;
  if (name == "relative_l2") return LossKind::RelativeL2;
  if (name == "l1") return LossKind::L1;
  throw InputError("unknown loss '" + name + "' (use l2, relative_l2 or l1)");
}

const char* lossName(LossKind k) {
  switch (k) {
    case LossKind::L2: return "l2";
    case LossKind::RelativeL2: return "relative_l2";
    default: return "l1";
  }
}

double imageLoss(LossKind kind, const Image& I, const Image& T, Image* adjoint, int viewsInBatch, const std::vector<float>* weights) {
  if (I.width() != T.width() || I.height() != T.height())
    throw InputError("target image is " + std::to_string(T.width()) + "x" + std::to_string(T.height()) + ", render is " +
                     std::to_string(I.width()) + "x" + std::to_string(I.height()));
  const size_t n = size_t(I.width()) * I.height();
  const double norm = 1.0 / (double(n) * 3.0 * viewsInBatch);
  if (adjoint) *adjoint = Image(I.width(), I.height(), 3);
  double sum = 0;
  for (size_t p = 0; p < n; ++p) {
    const double w = weights ? double((*weights)[p]) : 1.0;
    if (w == 0.0) continue;
    for (int c = 0; c < 3; ++c) {
      double i = I.data()[p * size_t(I.channels()) + size_t(c)];
      double t = T.data()[p * size_t(T.channels()) + size_t(std::min(c, T.channels() - 1))];
      double d = i - t, l, g;
      switch (kind) {
        case LossKind::L2: l = d * d; g = 2 * d; break;
        case LossKind::RelativeL2: { double w = 1.0 / (t * t + 0.01); l = d * d * w; g = 2 * d * w; break; }
        default: l = std::abs(d); g = d > 0 ? 1.0 : (d < 0 ? -1.0 : 0.0); break;
      }
      sum += w * l;
      if (adjoint) adjoint->data()[p * 3 + size_t(c)] = float(w * g * norm);
    }
  }
  return sum * norm;
}

double unbiasedImageLoss(LossKind kind, const Image& I1, const Image& I2, const Image& T, int viewsInBatch,
                         const std::vector<float>* weights) {
  for (const Image* I : {&I1, &I2})
    if (I->width() != T.width() || I->height() != T.height())
      throw InputError("target image is " + std::to_string(T.width()) + "x" + std::to_string(T.height()) + ", render is " +
                       std::to_string(I->width()) + "x" + std::to_string(I->height()));
  const size_t n = size_t(T.width()) * T.height();
  const double norm = 1.0 / (double(n) * 3.0 * viewsInBatch);
  double sum = 0;
  for (size_t p = 0; p < n; ++p) {
    const double w = weights ? double((*weights)[p]) : 1.0;
    if (w == 0.0) continue;
    for (int c = 0; c < 3; ++c) {
      double a = I1.data()[p * size_t(I1.channels()) + size_t(c)], b = I2.data()[p * size_t(I2.channels()) + size_t(c)];
      double t = T.data()[p * size_t(T.channels()) + size_t(std::min(c, T.channels() - 1))];
      double l;
      switch (kind) {
        case LossKind::L2: l = (a - t) * (b - t); break;
        case LossKind::RelativeL2: l = (a - t) * (b - t) / (t * t + 0.01); break;
        default: l = std::abs(0.5 * (a + b) - t); break;
      }
      sum += w * l;
    }
  }
  return sum * norm;
}

}  // namespace invr
