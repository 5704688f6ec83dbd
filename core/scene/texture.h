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
  Texture(std::shared_ptr<const Image> image, float scale) : image_(std::move(image)), scale_(scale) {}

  bool isConstant() const { return !image_; }
  Rgb constant() const { return constant_; }
  const Image* image() const { return image_.get(); }

  Rgb eval(Vec2 uv) const {
    if (!image_) return constant_;
    const Image& im = *image_;
    float x = (uv.x - std::floor(uv.x)) * float(im.width()) - 0.5f;
    float y = (1.f - (uv.y - std::floor(uv.y))) * float(im.height()) - 0.5f;
    int x0 = int(std::floor(x)), y0 = int(std::floor(y));
    float fx = x - float(x0), fy = y - float(y0);
    auto texel = [&](int ix, int iy) {
      ix = ((ix % im.width()) + im.width()) % im.width();
      iy = ((iy % im.height()) + im.height()) % im.height();
      return im.rgb(ix, iy);
    };
    Rgb v = texel(x0, y0) * ((1 - fx) * (1 - fy)) + texel(x0 + 1, y0) * (fx * (1 - fy)) +
            texel(x0, y0 + 1) * ((1 - fx) * fy) + texel(x0 + 1, y0 + 1) * (fx * fy);
    return v * scale_;
  }
  float evalScalar(Vec2 uv) const { return eval(uv).x; }

 private:
  Rgb constant_{0.f};
  std::shared_ptr<const Image> image_;
  float scale_ = 1.f;
};

}  // namespace invr
