// Surface textures: a constant or an image looked up bilinearly (texel centres at half-integers,
// repeat wrapping, v = 0 at the bottom row).
#pragma once

#include <memory>

#include "core/image/image.h"
#include "core/math/vec.h"

namespace invr {

class Texture {
 public:
  Texture() = default;
  explicit Texture(Rgb constant) : constant_(constant) {}
  Texture(std::shared_ptr<Image> image, float scale) : image_(std::move(image)), scale_(scale) {}

  bool isConstant() const { return !image_; }
  Rgb constant() const { return constant_; }
  const Image* image() const { return image_.get(); }
  float scale() const { return scale_; }
  // Parameter updates write through these (between renders, never during one).
  void setConstant(Rgb c) { constant_ = c; }
  Image* mutableImage() { return image_.get(); }

  Rgb eval(Vec2 uv) const {
    if (!image_) return constant_;
    Rgb v(0.f);
    forEachTexel(uv, [&](int x, int y, float w) { v += image_->rgb(x, y) * w; });
    return v * scale_;
  }
  // The four texels of the bilinear lookup at uv and their weights (which sum to one).
  template <typename F>
  void forEachTexel(Vec2 uv, F&& f) const {
    const Image& im = *image_;
    float x = (uv.x - std::floor(uv.x)) * float(im.width()) - 0.5f;
    float y = (1.f - (uv.y - std::floor(uv.y))) * float(im.height()) - 0.5f;
    int x0 = int(std::floor(x)), y0 = int(std::floor(y));
    float fx = x - float(x0), fy = y - float(y0);
    auto wrap = [](int i, int n) { return ((i % n) + n) % n; };
    int xa = wrap(x0, im.width()), xb = wrap(x0 + 1, im.width()), ya = wrap(y0, im.height()), yb = wrap(y0 + 1, im.height());
    f(xa, ya, (1 - fx) * (1 - fy));
    f(xb, ya, fx * (1 - fy));
    f(xa, yb, (1 - fx) * fy);
    f(xb, yb, fx * fy);
  }
  float evalScalar(Vec2 uv) const { return eval(uv).x; }

 private:
  Rgb constant_{0.f};
  std::shared_ptr<Image> image_;
  float scale_ = 1.f;
};

}  // namespace invr
