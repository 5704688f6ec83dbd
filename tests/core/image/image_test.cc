#include "core/image/image.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <map>
#include <unistd.h>

#include "core/error.h"
#include "core/limits.h"
#include "tests/test_util.h"

namespace invr {
namespace {

std::filesystem::path tmp(const std::string& name) {
  auto dir = std::filesystem::temp_directory_path() / ("invr_image_test_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  return dir / name;
}

Image gradient(int w, int h) {
  Image im(w, h, 3);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) im.setRgb(x, y, Rgb(float(x) / w, float(y) / h, 0.25f + 0.5f * float(x * y) / (w * h)));
  return im;
}

TEST(ImageIO, ExrRoundTripIsExact) {
  Image a = gradient(17, 9);
  a.at(3, 4, 0) = 1234.5f;  // HDR value
  writeImage(tmp("a.exr"), a);
  Image b = readImage(tmp("a.exr"));
  ASSERT_EQ(b.width(), 17);
  ASSERT_EQ(b.height(), 9);
  ASSERT_EQ(b.channels(), 3);
  EXPECT_EQ(a.data(), b.data());
}

TEST(ImageIO, PngRoundTripWithinQuantisation) {
  Image a = gradient(16, 16);
  writeImage(tmp("a.png"), a);
  Image b = readImage(tmp("a.png"));
  for (size_t i = 0; i < a.data().size(); ++i) {
    // One 8-bit sRGB step, expressed in linear units, is at most ~0.0125 near white.
    EXPECT_NEAR(a.data()[i], b.data()[i], 0.0125f) << i;
  }
}

TEST(ImageIO, HdrRoundTripWithinRgbePrecision) {
  Image a = gradient(8, 8);
  writeImage(tmp("a.hdr"), a);
  Image b = readImage(tmp("a.hdr"));
  for (size_t i = 0; i < a.data().size(); ++i) EXPECT_NEAR(a.data()[i], b.data()[i], 0.01f * a.data()[i] + 1e-3f);
}

TEST(ImageIO, MultiLayerExrKeepsNamedChannels) {
  Image rgb = gradient(5, 4), depth(5, 4, 1), normal(5, 4, 3);
  for (int i = 0; i < 20; ++i) depth.data()[size_t(i)] = float(i) * 0.5f;
  for (size_t i = 0; i < normal.data().size(); ++i) normal.data()[i] = -float(i);
  writeExrLayers(tmp("aov.exr"), {{"", {"R", "G", "B"}, rgb}, {"depth", {"Z"}, depth}, {"normal", {"X", "Y", "Z"}, normal}});
  auto layers = readExrLayers(tmp("aov.exr"));
  ASSERT_EQ(layers.size(), 3u);
  std::map<std::string, const ExrLayer*> byName;
  for (const auto& l : layers) byName[l.name] = &l;
  ASSERT_TRUE(byName.count("depth") && byName.count("normal") && byName.count(""));
  EXPECT_EQ(byName["depth"]->image.data(), depth.data());
  // Channels come back in the file's (alphabetical) order: B, G, R for the main layer.
  const ExrLayer& main = *byName[""];
  ASSERT_EQ(main.channels, (std::vector<std::string>{"B", "G", "R"}));
  for (int i = 0; i < 20; ++i) EXPECT_EQ(main.image.data()[size_t(i) * 3 + 2], rgb.data()[size_t(i) * 3]);
  const ExrLayer& n = *byName["normal"];
  ASSERT_EQ(n.channels, (std::vector<std::string>{"X", "Y", "Z"}));
  EXPECT_EQ(n.image.data(), normal.data());
}

TEST(ImageIO, ErrorsNameTheFile) {
  try {
    readImage(tmp("missing.png"));
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("missing.png"), std::string::npos);
  }
  std::ofstream(tmp("garbage.png")) << "not an image";
  EXPECT_THROW(readImage(tmp("garbage.png")), InputError);
  EXPECT_THROW(writeImage(tmp("x.bmpx"), gradient(2, 2)), InputError);
}

void writePngHeader(const std::filesystem::path& p, uint32_t w, uint32_t h) {
  std::ofstream(p, std::ios::binary) << test::pngDeclaringSize(w, h);
}

TEST(ImageIO, OversizedHeadersAreRefusedBeforeAllocating) {
  writePngHeader(tmp("huge.png"), 30000, 30000);  // 10 GB of float pixels if trusted
  try {
    readImage(tmp("huge.png"));
    FAIL() << "no error";
  } catch (const ResourceError& e) {
    EXPECT_NE(std::string(e.what()).find("30000x30000 pixels (limit 16384 per side)"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("huge.png"), std::string::npos) << e.what();
  }
  // In bounds per side but over what is left of a job's budget.
  writePngHeader(tmp("big.png"), 8192, 8192);
  MemoryBudget budget(uint64_t(100) << 20);
  try {
    readImage(tmp("big.png"), true, &budget);
    FAIL() << "no error";
  } catch (const ResourceError& e) {
    EXPECT_NE(std::string(e.what()).find("memory budget of 100 MiB"), std::string::npos) << e.what();
  }
  EXPECT_EQ(budget.used(), 0u);
  // Within the budget a header without pixels is a decode error, not a crash.
  writePngHeader(tmp("small.png"), 4, 4);
  MemoryBudget roomy(uint64_t(100) << 20);
  EXPECT_THROW(readImage(tmp("small.png"), true, &roomy), InputError);
}

TEST(ImageIO, MemoryBudgetCountsCharges) {
  MemoryBudget b(1000);
  b.charge(600, "a");
  EXPECT_EQ(b.used(), 600u);
  EXPECT_THROW(b.charge(401, "b"), ResourceError);
  b.charge(400, "c");
  EXPECT_EQ(b.used(), 1000u);
  EXPECT_THROW(b.charge(uint64_t(-1), "d"), ResourceError);  // no overflow
}

}  // namespace
}  // namespace invr
