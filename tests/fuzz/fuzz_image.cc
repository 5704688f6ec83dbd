// fuzz_png / fuzz_exr / fuzz_hdr: readImage on a file holding the input (OpenImageIO reads files by
// path), then the promises of core/image/image.h and core/limits.h. Built three times with
// INVR_FUZZ_IMAGE_EXT=".png", ".exr" and ".hdr": OpenImageIO picks its reader by extension (and
// tries the others when that one fails, as it does for a user's file).
#include <OpenImageIO/imageio.h>
#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>
#include <system_error>

#include "core/image/image.h"
#include "core/limits.h"
#include "tests/fuzz/fuzz_common.h"

#ifndef INVR_FUZZ_IMAGE_EXT
#error "define INVR_FUZZ_IMAGE_EXT as \".png\", \".exr\" or \".hdr\""
#endif

namespace {

constexpr uint64_t kBudgetBytes = uint64_t(256) << 20;

std::filesystem::path& scratchFile() {
  static std::filesystem::path path;
  return path;
}

void removeScratch() {
  std::error_code ec;
  std::filesystem::remove(scratchFile(), ec);
}

}  // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  // One file per process, in memory when /dev/shm is there (else $TMPDIR): several fuzzers (or
  // -jobs) can run side by side.
  std::error_code ec;
  std::filesystem::path dir = "/dev/shm";
  if (!std::filesystem::is_directory(dir, ec) || access(dir.c_str(), W_OK) != 0) dir = std::filesystem::temp_directory_path();
  scratchFile() = dir / ("invr-fuzz-" + std::to_string(getpid()) + INVR_FUZZ_IMAGE_EXT);
  std::atexit(removeScratch);
  // A run that crashed inside readImage left its file behind: remove those of dead processes.
  for (const auto& e : std::filesystem::directory_iterator(dir, ec)) {
    const std::string n = e.path().filename().string();
    if (n.rfind("invr-fuzz-", 0) != 0) continue;
    const std::string pid = n.substr(10, n.find('.') == std::string::npos ? std::string::npos : n.find('.') - 10);
    if (!pid.empty() && pid.find_first_not_of("0123456789") == std::string::npos && !std::filesystem::exists("/proc/" + pid, ec))
      std::filesystem::remove(e.path(), ec);
  }
  // Deterministic runs: no thread pool inside OpenImageIO / OpenEXR.
  OIIO::attribute("threads", 1);
  OIIO::attribute("exr_threads", 1);
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  {
    std::ofstream out(scratchFile(), std::ios::binary | std::ios::trunc);
    out.write(reinterpret_cast<const char*>(data), std::streamsize(size));
    if (!out) std::abort();  // the scratch directory is full: not a finding, but do not go on silently
  }
  // As the scene builder and the targets' loader call it: with the job's memory budget. A small
  // one (a job's default is 2 GiB), so that the fuzzer's 2 GB RSS limit catches what the budget
  // does not cover rather than the budget's own size.
  invr::MemoryBudget budget(kBudgetBytes);
  invr::Image img;
  try {
    img = invr::readImage(scratchFile(), /*srgbToLinear=*/size % 2 == 0, &budget);
  } catch (const invr::InputError& e) {
    removeScratch();
    invr::fuzz::rejected(e);
    return 0;
  }
  // Removed after every input (not only at exit): a crash ends the process without atexit.
  removeScratch();
  const int side = invr::inputLimits().maxImageSide;
  FUZZ_CHECK(img.width() > 0 && img.height() > 0, std::to_string(img.width()) + "x" + std::to_string(img.height()));
  FUZZ_CHECK(img.width() <= side && img.height() <= side,
             std::to_string(img.width()) + "x" + std::to_string(img.height()) + " beyond the side limit " + std::to_string(side));
  FUZZ_CHECK(img.channels() >= 1 && img.channels() <= 4, std::to_string(img.channels()) + " channels");
  FUZZ_CHECK(img.data().size() == size_t(img.width()) * img.height() * img.channels(), "pixel buffer size");
  FUZZ_CHECK(budget.used() >= img.data().size() * sizeof(float), "the image is larger than the budget charged for it");
  // Touch every value (and the accessors) so a short buffer shows up under ASan.
  double sum = 0;
  for (float v : img.data()) sum += v;
  invr::Rgb corner = img.rgb(img.width() - 1, img.height() - 1);
  invr::fuzz::accepted(std::to_string(img.width()) + "x" + std::to_string(img.height()) + "x" + std::to_string(img.channels()) +
                       " sum " + std::to_string(sum) + " corner " + std::to_string(corner.x));
  return 0;
}
