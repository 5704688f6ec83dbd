#include "core/image/image.h"

#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfInputFile.h>
#include <OpenEXR/ImfOutputFile.h>

#include <OpenImageIO/imageio.h>

#include <algorithm>
#include <cmath>
#include <map>

#include "core/error.h"
#include "core/limits.h"

namespace invr {

float srgbToLinear(float v) {
  return v <= 0.04045f ? v / 12.92f : std::pow((v + 0.055f) / 1.055f, 2.4f);
}
float linearToSrgb(float v) {
  return v <= 0.0031308f ? 12.92f * v : 1.055f * std::pow(v, 1.f / 2.4f) - 0.055f;
}

Image readImage(const std::filesystem::path& path, bool srgbToLinearConv, MemoryBudget* budget) {
  const std::string name = "image '" + path.string() + "'";
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec)) throw InputError(name + ": file not found");
  const InputLimits& lim = inputLimits();
  uint64_t fileBytes = std::filesystem::file_size(path, ec);
  if (!ec && fileBytes > lim.maxFileBytes)
    throw ResourceError(name + ": " + humanBytes(fileBytes) + " (limit " + humanBytes(lim.maxFileBytes) + ")");
  auto in = OIIO::ImageInput::open(path.string());
  if (!in) throw InputError(name + ": cannot read (" + OIIO::geterror() + ")");
  const OIIO::ImageSpec& spec = in->spec();
  // The header is all that has been read so far: check what it declares before allocating.
  if (spec.width <= 0 || spec.height <= 0 || spec.nchannels <= 0) throw InputError(name + ": empty image");
  if (spec.depth > 1) throw InputError(name + ": a 3-D image (depth " + std::to_string(spec.depth) + ") is not a texture");
  if (spec.width > lim.maxImageSide || spec.height > lim.maxImageSide)
    throw ResourceError(name + ": " + std::to_string(spec.width) + "x" + std::to_string(spec.height) + " pixels (limit " +
                        std::to_string(lim.maxImageSide) + " per side)");
  if (spec.nchannels > 64) throw InputError(name + ": " + std::to_string(spec.nchannels) + " channels (at most 64 are read)");
  int channels = std::min(spec.nchannels, 4);
  const uint64_t pixels = uint64_t(spec.width) * uint64_t(spec.height);
  // The image kept, and the decode buffer of every channel beside it while this call runs: the
  // peak is what a budget has to cover.
  const uint64_t keptBytes = pixels * uint64_t(channels) * sizeof(float);
  const uint64_t decodeBytes = pixels * uint64_t(spec.nchannels) * sizeof(float);
  if (budget) budget->charge(keptBytes + decodeBytes, name);
  if (decodeBytes > (uint64_t(4) << 30)) throw ResourceError(name + ": decoding needs " + humanBytes(decodeBytes) + " (limit 4 GiB)");
  Image img(spec.width, spec.height, channels);
  std::vector<float> all(size_t(pixels) * size_t(spec.nchannels));
  if (!in->read_image(0, 0, 0, spec.nchannels, OIIO::TypeDesc::FLOAT, all.data()))
    throw InputError(name + ": decode failed (" + in->geterror() + ")");
  bool eightBit = spec.format.basetype == OIIO::TypeDesc::UINT8 || spec.format.basetype == OIIO::TypeDesc::UINT16;
  bool linearize = srgbToLinearConv && eightBit && spec.get_string_attribute("oiio:ColorSpace") != "Linear";
  for (size_t p = 0; p < size_t(pixels); ++p) {
    for (int c = 0; c < channels; ++c) {
      float v = all[p * size_t(spec.nchannels) + size_t(c)];
      if (linearize && c < 3) v = srgbToLinear(v);
      img.data()[p * size_t(channels) + size_t(c)] = v;
    }
  }
  return img;
}

void writeImage(const std::filesystem::path& path, const Image& image) {
  std::string ext = path.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), ::tolower);
  if (ext != ".exr" && ext != ".png" && ext != ".hdr")
    throw InputError("output '" + path.string() + "': unsupported extension (use .exr, .png or .hdr)");
  if (path.has_parent_path()) std::filesystem::create_directories(path.parent_path());
  auto out = OIIO::ImageOutput::create(path.string());
  if (!out) throw InputError("output '" + path.string() + "': " + OIIO::geterror());
  int c = image.channels();
  if (ext == ".png") {
    int oc = std::min(c, 4);
    std::vector<uint8_t> px(size_t(image.width()) * image.height() * oc);
    for (size_t p = 0; p < size_t(image.width()) * image.height(); ++p)
      for (int k = 0; k < oc; ++k) {
        float v = image.data()[p * c + k];
        if (k < 3) v = linearToSrgb(std::clamp(v, 0.f, 1.f));
        px[p * oc + k] = uint8_t(std::lround(std::clamp(v, 0.f, 1.f) * 255.f));
      }
    OIIO::ImageSpec spec(image.width(), image.height(), oc, OIIO::TypeDesc::UINT8);
    if (!out->open(path.string(), spec) || !out->write_image(OIIO::TypeDesc::UINT8, px.data()))
      throw InputError("output '" + path.string() + "': " + out->geterror());
  } else {
    int oc = ext == ".hdr" ? 3 : c;
    std::vector<float> px(size_t(image.width()) * image.height() * oc);
    for (size_t p = 0; p < size_t(image.width()) * image.height(); ++p)
      for (int k = 0; k < oc; ++k) px[p * oc + k] = image.data()[p * c + std::min(k, c - 1)];
    OIIO::ImageSpec spec(image.width(), image.height(), oc, OIIO::TypeDesc::FLOAT);
    if (!out->open(path.string(), spec) || !out->write_image(OIIO::TypeDesc::FLOAT, px.data()))
      throw InputError("output '" + path.string() + "': " + out->geterror());
  }
  out->close();
}

void writeExrLayers(const std::filesystem::path& path, const std::vector<ExrLayer>& layers) {
  if (layers.empty()) throw InputError("exr '" + path.string() + "': no layers to write");
  int w = layers[0].image.width(), h = layers[0].image.height();
  Imf::Header header(w, h);
  Imf::FrameBuffer fb;
  for (const auto& layer : layers) {
    if (layer.image.width() != w || layer.image.height() != h || size_t(layer.image.channels()) != layer.channels.size())
      throw InputError("exr '" + path.string() + "': layer '" + layer.name + "' has mismatched size or channel count");
    for (size_t c = 0; c < layer.channels.size(); ++c) {
      std::string name = layer.name.empty() ? layer.channels[c] : layer.name + "." + layer.channels[c];
      header.channels().insert(name, Imf::Channel(Imf::FLOAT));
      size_t stride = sizeof(float) * layer.channels.size();
      fb.insert(name, Imf::Slice(Imf::FLOAT, (char*)(layer.image.data().data() + c), stride, stride * w));
    }
  }
  if (path.has_parent_path()) std::filesystem::create_directories(path.parent_path());
  Imf::OutputFile file(path.string().c_str(), header);
  file.setFrameBuffer(fb);
  file.writePixels(h);
}

std::vector<ExrLayer> readExrLayers(const std::filesystem::path& path) {
  if (!std::filesystem::exists(path)) throw InputError("exr '" + path.string() + "': file not found");
  try {
    Imf::InputFile file(path.string().c_str());
    auto dw = file.header().dataWindow();
    int64_t w64 = int64_t(dw.max.x) - dw.min.x + 1, h64 = int64_t(dw.max.y) - dw.min.y + 1;
    if (w64 <= 0 || h64 <= 0 || w64 > inputLimits().maxImageSide || h64 > inputLimits().maxImageSide)
      throw ResourceError("exr '" + path.string() + "': data window " + std::to_string(w64) + "x" + std::to_string(h64) +
                          " (limit " + std::to_string(inputLimits().maxImageSide) + " per side)");
    int w = int(w64), h = int(h64);
    std::map<std::string, std::vector<std::string>> groups;  // ordered: deterministic layer order
    for (auto it = file.header().channels().begin(); it != file.header().channels().end(); ++it) {
      std::string full = it.name();
      auto dot = full.rfind('.');
      groups[dot == std::string::npos ? "" : full.substr(0, dot)].push_back(dot == std::string::npos ? full : full.substr(dot + 1));
    }
    std::vector<ExrLayer> layers;
    for (auto& [name, chans] : groups) layers.push_back({name, chans, Image(w, h, int(chans.size()))});
    Imf::FrameBuffer fb;
    for (auto& layer : layers)
      for (size_t c = 0; c < layer.channels.size(); ++c) {
        std::string full = layer.name.empty() ? layer.channels[c] : layer.name + "." + layer.channels[c];
        size_t stride = sizeof(float) * layer.channels.size();
        char* base = (char*)(layer.image.data().data() + c) - (dw.min.x + size_t(dw.min.y) * w) * stride;
        fb.insert(full, Imf::Slice(Imf::FLOAT, base, stride, stride * w));
      }
    file.setFrameBuffer(fb);
    file.readPixels(dw.min.y, dw.max.y);
    return layers;
  } catch (const InputError&) {
    throw;
  } catch (const std::exception& e) {
    throw InputError("exr '" + path.string() + "': " + e.what());
  }
}

}  // namespace invr
