// fuzz_mitsuba_xml: importMitsubaSceneText (the bytes of a user's Mitsuba 3 scene file), then the
// promises an accepted import makes: a job within the input limits, at least one view and one
// light, every shape's material and every area light's shape present, finite numbers.
// File references resolve in an empty folder, so they fail as missing files (or, absolute, as
// whatever the path is: never read if not a regular file).
#include <unistd.h>

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <set>
#include <string>

#include "core/io/job_io.h"
#include "core/io/mitsuba_import.h"
#include "tests/fuzz/fuzz_common.h"

namespace {

const std::filesystem::path& emptyDir() {
  static const std::filesystem::path dir = [] {
    auto d = std::filesystem::temp_directory_path() / ("invr_fuzz_mitsuba_" + std::to_string(::getpid()));
    std::filesystem::create_directories(d);
    return d;
  }();
  return dir;
}

bool finite(const invr::v1::Vec3& v) { return std::isfinite(v.x()) && std::isfinite(v.y()) && std::isfinite(v.z()); }
bool finite(const invr::v1::Rgb& c) { return std::isfinite(c.r()) && std::isfinite(c.g()) && std::isfinite(c.b()); }

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string bytes(reinterpret_cast<const char*>(data), size);
  invr::MitsubaImport imp;
  try {
    imp = invr::importMitsubaSceneText(bytes, emptyDir(), "fuzz.xml");
  } catch (const invr::InputError& e) {
    invr::fuzz::rejected(e);
    return 0;
  }
  const auto& s = imp.job.scene();
  try {
    invr::validateJobSpec(imp.job);
  } catch (const invr::InputError& e) {
    FUZZ_CHECK(false, std::string("an accepted import breaks the job limits: ") + e.what());
  }
  FUZZ_CHECK(s.views_size() > 0, "no view");
  FUZZ_CHECK(s.lights_size() > 0, "no light");
  FUZZ_CHECK(s.film().width() > 0 && s.film().height() > 0, "film size");
  std::set<std::string> materials, shapes;
  for (const auto& m : s.materials()) FUZZ_CHECK(materials.insert(m.name()).second, "duplicate material " + m.name());
  for (const auto& sh : s.shapes()) {
    FUZZ_CHECK(shapes.insert(sh.name()).second, "duplicate shape " + sh.name());
    FUZZ_CHECK(materials.count(sh.material()) == 1, "shape " + sh.name() + " has no material");
    for (double x : sh.transform().matrix()) FUZZ_CHECK(std::isfinite(x), "non-finite transform");
  }
  for (const auto& l : s.lights()) {
    if (l.has_area()) {
      FUZZ_CHECK(shapes.count(l.area().shape()) == 1, "area light on a missing shape");
      FUZZ_CHECK(finite(l.area().radiance()), "radiance");
    }
    if (l.has_point()) FUZZ_CHECK(finite(l.point().position()) && finite(l.point().intensity()), "point light");
    if (l.has_spot()) FUZZ_CHECK(finite(l.spot().position()) && finite(l.spot().target()), "spot light");
  }
  for (const auto& v : s.views()) {
    FUZZ_CHECK(finite(v.eye()) && finite(v.target()) && finite(v.up()), "camera");
    FUZZ_CHECK(v.fov_y_degrees() > 0 && v.fov_y_degrees() < 180, "fov " + std::to_string(v.fov_y_degrees()));
  }
  invr::fuzz::accepted(std::to_string(s.shapes_size()) + " shapes, " + std::to_string(s.lights_size()) + " lights");
  return 0;
}
