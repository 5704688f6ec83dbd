// Every registered parameter kind (core/diff/parameter_kind.h), whatever it is: `invr params`
// lists it in a scene that has one, its values survive a write and a read, and a scene exported
// to Mitsuba and imported back holds the values written (poses baked into the geometry, sampling
// values carried by jobs instead). A new kind is checked here without a line of this file.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <map>
#include <string>

#include "core/diff/parameter_catalog.h"
#include "core/diff/parameter_kind.h"
#include "core/error.h"
#include "core/io/mitsuba_import.h"
#include "core/job/problem.h"
#include "core/job/zoo_jobs.h"
#include "core/scene/mitsuba_export.h"
#include "core/scene/scene_builder.h"

namespace invr {
namespace {

namespace fs = std::filesystem;

// Zoo jobs' scenes that between them hold every kind (the roulette job's scene has fixed-survival
// roulette; the others as the zoo builds them).
const std::vector<std::string> kScenes = {"cornell", "mirror", "oxalis", "skylight", "tree", "roulette"};

struct Found {
  std::string scene, name;
};

// The first name of `kind` that `invr params` lists in one of the scenes (built once each).
Found firstOfKind(const ParameterKind& kind, std::map<std::string, std::unique_ptr<Problem>>& problems) {
  for (const std::string& z : kScenes) {
    auto& p = problems[z];
    if (!p) p = std::make_unique<Problem>(buildProblem(zooJob(z)));
    for (const ParameterInfo& info : optimisableParameters(*p->scene))
      if (info.kind == kind.name()) return {z, info.name};
  }
  return {};
}

// Values other than the scene's, within the bounds: a vertex or a pose moves by a small amount
// that differs per component, everything else a fifth of the way towards its bounds' middle (or
// up by a quarter when unbounded above).
std::vector<float> nudged(const ParameterSlot& s, std::vector<float> v) {
  for (size_t k = 0; k < v.size(); ++k) {
    float& x = v[k];
    if (s.kind->relativeToGeometry()) x += 0.01f * float(1 + k % 7);
    else x = std::isfinite(s.upper) ? x + 0.2f * (0.5f * (s.lower + s.upper) - x) + 0.001f : x * 1.25f + 0.01f;
    x = std::clamp(x, s.lower, s.upper);
  }
  return v;
}

TEST(ParameterKind, EveryKindIsListedRoundTripsAndExports) {
  ASSERT_GE(parameterKinds().size(), 11u);
  std::map<std::string, std::unique_ptr<Problem>> problems;
  const fs::path dir = fs::temp_directory_path() / ("invr_parameter_kind_" + std::to_string(::getpid()));
  for (const ParameterKind* kind : parameterKinds()) {
    SCOPED_TRACE(kind->name());
    const Found f = firstOfKind(*kind, problems);
    ASSERT_FALSE(f.name.empty()) << "no scene of " << testing::PrintToString(kScenes) << " lists a parameter of kind " << kind->name();
    // A scene of its own: a mesh that moved rigidly cannot deform afterwards (and vice versa).
    Problem fresh = buildProblem(zooJob(f.scene));
    Scene& scene = *fresh.scene;
    ParameterRegistry reg;
    const ParameterSlot& s = reg.add(scene, f.name);
    EXPECT_EQ(s.kind, kind);
    EXPECT_EQ(reg.size(), s.size);
    const std::vector<float> before = reg.read(scene), theta = nudged(s, before);
    ASSERT_NE(theta, before);
    reg.write(theta, scene);
    const std::vector<float> back = reg.read(scene);
    ASSERT_EQ(back.size(), theta.size());
    for (size_t k = 0; k < theta.size(); ++k) ASSERT_NEAR(back[k], theta[k], 1e-5f * (1.f + std::abs(theta[k]))) << f.name << " value " << k;

    // Exported and imported back: the scene holds the values, except what it cannot hold.
    if (!kind->changesNoiseOnly()) {
      fs::remove_all(dir);
      const fs::path xml = dir / "scene.xml";
      const MitsubaExport written = exportMitsubaScene(scene, xml);
      AssetResolver assets;
      assets.baseDir = dir;
      std::unique_ptr<Scene> imported = buildJobScene(importMitsubaScene(xml).job, assets);
      ParameterRegistry again;
      std::string name = f.name;  // the export may rename a shape whose name another object took
      for (const auto& [from, to] : written.renamed)
        if (name.rfind(from, 0) == 0) name = to + name.substr(from.size());
      const ParameterSlot& t = again.add(*imported, name);
      EXPECT_EQ(t.kind, kind);
      const std::vector<float> exported = again.read(*imported);
      ASSERT_EQ(exported.size(), theta.size());
      const bool baked = kind->relativeToGeometry() && !kind->isMesh();  // a pose is part of the exported meshes
      for (size_t k = 0; k < theta.size(); ++k) {
        const float expected = !baked ? theta[k] : std::string(kind->name()) == "scale" ? 1.f : 0.f;
        ASSERT_NEAR(exported[k], expected, 1e-4f * (1.f + std::abs(expected))) << f.name << " value " << k << " after export";
      }
    }
  }
  fs::remove_all(dir);
}

// The registry's refusals come from the kinds it has: an unknown group or property lists them.
TEST(ParameterKind, UnknownNamesListTheRegisteredKinds) {
  auto p = buildProblem(zooJob("cornell"));
  ParameterRegistry reg;
  auto message = [&](const std::string& name) {
    try {
      reg.add(*p.scene, name);
    } catch (const InputError& e) {
      return std::string(e.what());
    }
    return std::string("accepted");
  };
  const std::string group = message("films/front/size");
  for (const ParameterKind* k : parameterKinds())
    for (const std::string& g : k->groups()) EXPECT_NE(group.find(g), std::string::npos) << group;
  const std::string property = message("lights/" + p.scene->lights[0].name + "/colour");
  EXPECT_NE(property.find("unknown light property 'colour' (use intensity or texels)"), std::string::npos) << property;
}

}  // namespace
}  // namespace invr
