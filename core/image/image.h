// Float images in linear RGB(A) and their file IO (PNG, EXR, HDR through OpenImageIO; multi-layer
// EXR with named channels through OpenEXR).
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include "core/math/vec.h"

namespace invr {

class Image {
 public:
  Image() = default;
  Image(int width, int height, int channels) : w_(width), h_(height), c_(channels), data_(size_t(width) * height * channels, 0.f) {}

  int width() const { return w_; }
  int height() const { return h_; }
  int channels() const { return c_; }
  bool empty() const { return data_.empty(); }
  float& at(int x, int y, int ch) { return data_[(size_t(y) * w_ + x) * c_ + ch]; }
  float at(int x, int y, int ch) const { return data_[(size_t(y) * w_ + x) * c_ + ch]; }
  Rgb rgb(int x, int y) const {
    const float* p = &data_[(size_t(y) * w_ + x) * c_];
    return c_ >= 3 ? Rgb(p[0], p[1], p[2]) : Rgb(p[0]);
  }
  void setRgb(int x, int y, Rgb v) {
    float* p = &data_[(size_t(y) * w_ + x) * c_];
    p[0] = v.x;
    if (c_ >= 3) { p[1] = v.y; p[2] = v.z; }
  }
  std::vector<float>& data() { return data_; }
  const std::vector<float>& data() const { return data_; }

 private:
  int w_ = 0, h_ = 0, c_ = 0;
  std::vector<float> data_;
};

// Reads any format OpenImageIO knows. 8-bit formats (PNG, JPEG) are converted from sRGB to
// linear when `srgbToLinear` (true for colour textures, false for data such as roughness).
// Throws InputError naming the file when it cannot be read. The header's size is checked before
// any pixel memory is allocated: sides beyond inputLimits().maxImageSide, more than 4 channels
// kept of at most 64, 3-D images, or (with a budget) more bytes than the budget has left throw
// ResourceError naming the file and the limit.
class MemoryBudget;
Image readImage(const std::filesystem::path& path, bool srgbToLinear = true, MemoryBudget* budget = nullptr);

// Writes by extension: .exr (32-bit float), .hdr, .png (clamped, sRGB-encoded 8-bit).
void writeImage(const std::filesystem::path& path, const Image& image);

// One named layer of a multi-layer EXR: channels are written as "<layer>.<name>".
struct ExrLayer {
  std::string name;                  // e.g. "albedo"; empty for the main RGB
  std::vector<std::string> channels; // e.g. {"R","G","B"}
  Image image;                       // channels() == channels.size()
};
void writeExrLayers(const std::filesystem::path& path, const std::vector<ExrLayer>& layers);
// Reads every channel of an EXR, grouped by layer prefix (text before the last '.').
std::vector<ExrLayer> readExrLayers(const std::filesystem::path& path);

float srgbToLinear(float v);
float linearToSrgb(float v);

}  // namespace invr
