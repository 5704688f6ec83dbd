// Camera parameters (core/diff/param_camera.cc): the pose kinds themselves (names, round trip,
// the camera they place, their velocity fields), the job check's refusals, and whole
// gradient-engine steps against finite differences of the converged loss (tests/core/diff/
// visibility_case.h): the interior term alone (a plane filling the view), a shadow border
// carrying the derivative, and silhouettes, creases and shadows together for translation and
// rotation with PT and RIS (ReSTIR in the deep suite). Moving the camera moves every point of the
// image, so each term has a part here that a shape's motion never exercises.
#include <gtest/gtest.h>

#include <cmath>
#include <string>

#include "core/diff/boundary_term.h"
#include "core/diff/gradient_job_check.h"
#include "core/diff/parameter_catalog.h"
#include "core/diff/parameter_kind.h"
#include "core/error.h"
#include "core/diff/diff_scenes.h"
#include "core/diff/visibility_case.h"

namespace invr {
namespace {

using test::Check;
using test::MeanSE;
using test::ShapeCase;

// A box held above a floor that fills the view, under a small area light out of view: the box's
// silhouette and creases, and its shadow on the floor, all move on the film with the camera.
constexpr const char* kBoxScene = R"({
  "materials": [{"name": "grey", "diffuse": {"albedo": {"constant": {"r": 0.6, "g": 0.5, "b": 0.4}}}},
                {"name": "red", "diffuse": {"albedo": {"constant": {"r": 0.7, "g": 0.2, "b": 0.15}}}},
                {"name": "white", "diffuse": {"albedo": {"constant": {"r": 0.8, "g": 0.8, "b": 0.8}}}}],
  "shapes": [
    {"name": "floor", "quad": {}, "material": "grey", "transform": {"scale": {"x": 4, "y": 4, "z": 1}}},
    {"name": "box", "box": {}, "material": "red",
     "transform": {"scale": {"x": 0.3, "y": 0.25, "z": 0.2}, "rotate_xyz_degrees": {"x": 10, "z": 25}, "translate": {"x": -0.3, "y": 0.2, "z": 0.45}}},
    {"name": "lamp", "quad": {}, "material": "white",
     "transform": {"scale": {"x": 0.15, "y": 0.15, "z": 1}, "rotate_xyz_degrees": {"x": 180}, "translate": {"x": 1.2, "y": -0.3, "z": 4}}}],
  "lights": [{"name": "lamp", "area": {"shape": "lamp", "radiance": {"r": 130, "g": 130, "b": 130}}}],
  "views": [{"name": "cam", "eye": {"x": 0.3, "y": -2.5, "z": 3}, "target": {}, "up": {"z": 1}, "fov_y_degrees": 40}],
  "film": {"width": 40, "height": 30}})";

// A plane filling the view under a point light: nothing on the film has an edge, so the camera's
// interior term (the ray moving, its hit sliding along the plane) is the whole derivative.
constexpr const char* kPlaneScene = R"({
  "materials": [{"name": "grey", "diffuse": {"albedo": {"constant": {"r": 0.6, "g": 0.5, "b": 0.4}}}}],
  "shapes": [{"name": "plane", "quad": {}, "material": "grey", "transform": {"scale": {"x": 4, "y": 4, "z": 1}}}],
  "lights": [{"name": "bulb", "point": {"position": {"x": 0.7, "y": -0.5, "z": 1.4}, "intensity": {"r": 6, "g": 6, "b": 6}}}],
  "views": [{"eye": {"z": 4}, "target": {}, "up": {"y": 1}, "fov_y_degrees": 40}],
  "film": {"width": 40, "height": 40}})";

// A floor filling the view under a far point light (its shading nearly uniform), and a card out
// of view above it whose shadow falls across the middle of the film: moving the camera sideways
// moves that shadow's border on the film, which carries the derivative (the secondary term).
constexpr const char* kShadowScene = R"({
  "materials": [{"name": "grey", "diffuse": {"albedo": {"constant": {"r": 0.6, "g": 0.5, "b": 0.4}}}},
                {"name": "white", "diffuse": {"albedo": {"constant": {"r": 0.8, "g": 0.8, "b": 0.8}}}}],
  "shapes": [
    {"name": "floor", "quad": {}, "material": "grey", "transform": {"scale": {"x": 6, "y": 6, "z": 1}}},
    {"name": "card", "quad": {}, "material": "white",
     "transform": {"scale": {"x": 0.5, "y": 0.5, "z": 1}, "rotate_xyz_degrees": {"z": 17}, "translate": {"x": 1.5, "y": 0.3, "z": 2.5}}}],
  "lights": [{"name": "sun", "point": {"position": {"x": 9, "y": 1.8, "z": 15}, "intensity": {"r": 600, "g": 600, "b": 600}}}],
  "views": [{"eye": {"z": 4}, "target": {}, "up": {"y": 1}, "fov_y_degrees": 40}],
  "film": {"width": 40, "height": 40}})";

GradientOptions cameraOptions(GradientMethod method) {
  GradientOptions o = test::shapeOptions(method);
  o.boundary.samples = 2048;  // every edge of the view moves: more of them than a moving shape has
  return o;
}

// ---- the kinds ----------------------------------------------------------------------------------

TEST(CameraPose, NamesReadWriteAndThePlacedCamera) {
  auto scene = test::sceneFromJson(kBoxScene);
  const Camera rest = scene->cameras[0];
  ParameterRegistry reg;
  const ParameterSlot& t = reg.add(*scene, "cameras/cam/translation");
  const ParameterSlot& r = reg.add(*scene, "cameras/0/rotation/z");  // by index, one component
  EXPECT_STREQ(t.kind->name(), "camera_translation");
  EXPECT_STREQ(r.kind->name(), "camera_rotation");
  EXPECT_EQ(reg.size(), 4u);
  EXPECT_TRUE(reg.hasCameraParameters());
  EXPECT_TRUE(reg.movesCamera(0));
  EXPECT_EQ(reg.read(*scene), std::vector<float>(4, 0.f));
  // Turned 90 degrees about the world's z (up here): the look direction turns with it, the eye
  // moves by the translation only.
  reg.write({0.1f, -0.2f, 0.3f, 90.f}, *scene);
  EXPECT_EQ(reg.read(*scene), (std::vector<float>{0.1f, -0.2f, 0.3f, 90.f}));
  const Camera& c = scene->cameras[0];
  EXPECT_NEAR(length(c.eye - (rest.eye + Vec3(0.1f, -0.2f, 0.3f))), 0.f, 1e-5f);
  const Vec3 turned(-rest.forward.y, rest.forward.x, rest.forward.z);
  EXPECT_NEAR(length(c.forward - turned), 0.f, 1e-5f);
  EXPECT_NEAR(dot(c.forward, c.up), 0.f, 1e-5f);
  EXPECT_GT(scene->cameraVersion(), 0u);
  // Back at 0: the camera as described.
  reg.write({0.f, 0.f, 0.f, 0.f}, *scene);
  EXPECT_NEAR(length(scene->cameras[0].eye - rest.eye), 0.f, 1e-6f);
  EXPECT_NEAR(length(scene->cameras[0].forward - rest.forward), 0.f, 1e-6f);
}

// The velocity field a camera component moves a point with (what the estimators scatter through)
// against the finite difference of the camera's own placement: a point fixed in the camera's
// frame, at a pose away from the rest pose (Euler rotations do not commute there).
TEST(CameraPose, VelocityFieldsAreTheDerivativeOfThePlacement) {
  auto scene = test::sceneFromJson(kBoxScene);
  ParameterRegistry reg;
  reg.add(*scene, "cameras/cam/translation");
  reg.add(*scene, "cameras/cam/rotation");
  const std::vector<float> theta = {0.05f, -0.1f, 0.2f, 12.f, -20.f, 35.f};
  // A point at camera coordinates (a, b, c): eye + a right + b up + c forward.
  auto attached = [&](const std::vector<float>& t) {
    reg.write(t, *scene);
    const Camera& c = scene->cameras[0];
    return c.eye + c.right * 0.3f + c.up * -0.2f + c.forward * 2.f;
  };
  const Vec3 p = attached(theta);
  for (int k = 0; k < 6; ++k) {
    reg.write(theta, *scene);
    const Vec3 v = scene->cameraPointVelocity(0, k, p);
    const float h = k < 3 ? 1e-3f : 0.05f;
    std::vector<float> plus = theta, minus = theta;
    plus[size_t(k)] += h;
    minus[size_t(k)] -= h;
    const Vec3 fd = (attached(plus) - attached(minus)) / (2.f * h);
    EXPECT_NEAR(length(v - fd), 0.f, 2e-3f * (1.f + length(fd))) << "component " << k;
  }
}

TEST(CameraPose, EveryViewTogetherAndTheRefusals) {
  auto two = test::sceneFromJson(R"({
    "materials": [{"name": "grey", "diffuse": {"albedo": {"constant": {"r": 0.5, "g": 0.5, "b": 0.5}}}}],
    "shapes": [{"name": "floor", "quad": {}, "material": "grey"}],
    "lights": [{"name": "bulb", "point": {"position": {"z": 2}, "intensity": {"r": 1, "g": 1, "b": 1}}}],
    "views": [{"name": "a", "eye": {"z": 3}, "target": {}, "up": {"y": 1}},
              {"name": "b", "eye": {"x": 1, "z": 3}, "target": {}, "up": {"y": 1}}],
    "film": {"width": 8, "height": 8}})");
  const Vec3 a = two->cameras[0].eye, b = two->cameras[1].eye;
  ParameterRegistry reg;
  reg.add(*two, "cameras/*/translation");
  EXPECT_TRUE(reg.movesCamera(0) && reg.movesCamera(1));
  reg.write({0.f, 0.5f, 0.f}, *two);
  EXPECT_NEAR(two->cameras[0].eye.y - a.y, 0.5f, 1e-6f);
  EXPECT_NEAR(two->cameras[1].eye.y - b.y, 0.5f, 1e-6f);
  auto refusal = [&](const std::string& name) {
    try {
      reg.add(*two, name);
    } catch (const InputError& e) {
      return std::string(e.what());
    }
    return std::string("accepted");
  };
  EXPECT_NE(refusal("cameras/a/translation/y").find("listed twice"), std::string::npos);
  EXPECT_NE(refusal("cameras/c/rotation").find("no camera named 'c'"), std::string::npos);
  EXPECT_NE(refusal("cameras/a/fov").find("unknown camera property 'fov' (use translation or rotation)"), std::string::npos)
      << refusal("cameras/a/fov");
  // `invr params` lists each view's and the rig's.
  bool rig = false, named = false;
  for (const ParameterInfo& info : optimisableParameters(*two)) {
    rig = rig || info.name == "cameras/*/rotation";
    named = named || info.name == "cameras/b/translation";
  }
  EXPECT_TRUE(rig && named);
}

// What a moving camera cannot differentiate is refused by name: a textured or glossy surface in
// view (the interior term covers diffuse untextured ones), an image environment (its texel borders
// move on the film), surfaces that touch (their contact curve is not a mesh edge).
TEST(CameraPose, TheJobCheckRefusesWhatNoTermCovers) {
  auto message = [](const std::string& json) {
    auto scene = test::sceneFromJson(json.c_str());
    ParameterRegistry reg;
    reg.add(*scene, "cameras/0/translation");
    GradientOptions o;
    try {
      validateGradientJob(*scene, reg, o);
    } catch (const InputError& e) {
      return std::string(e.what());
    }
    return std::string("accepted");
  };
  EXPECT_EQ(message(kBoxScene), "accepted");
  const std::string textured = message(test::kDiffScene);
  EXPECT_NE(textured.find("camera parameters: shape 'wall' has material 'wall'"), std::string::npos) << textured;
  std::string touching = kBoxScene;
  touching.replace(touching.find("\"z\": 0.45"), 9, "\"z\": 0.1");  // the box now cuts the floor
  const std::string cut = message(touching);
  EXPECT_NE(cut.find("shapes 'floor' and 'box' touch or cut each other"), std::string::npos) << cut;
  std::string sky = kBoxScene;
  sky.replace(sky.find("\"lights\": ["), 11,
              R"("lights": [{"name": "sky", "environment": {"radiance": {"procedural": {"pattern": "sun_sky", "width": 8, "height": 4}}}}, )");
  const std::string env = message(sky);
  EXPECT_NE(env.find("environment map 'sky'"), std::string::npos) << env;
}

// The refusals are computed from what the terms declare they sample: against no terms at all
// every moving discontinuity of the box scene is named (its edges, the lamp's shadows); against
// the registered ones none is; a term declaring contact curves would take the floor contact off
// the list.
TEST(CameraPose, RefusalsFollowWhatTheTermsDeclare) {
  std::string touching = kBoxScene;
  touching.replace(touching.find("\"z\": 0.45"), 9, "\"z\": 0.1");
  auto scene = test::sceneFromJson(touching.c_str());
  ParameterRegistry reg;
  reg.add(*scene, "cameras/0/rotation");
  const std::vector<std::string> none = unsampledDiscontinuities(*scene, reg, {});
  ASSERT_EQ(none.size(), 3u) << testing::PrintToString(none);
  EXPECT_NE(none[0].find("the edges of every shape in a moving view"), std::string::npos) << none[0];
  EXPECT_NE(none[1].find("light 'lamp' casts shadows"), std::string::npos) << none[1];
  EXPECT_NE(none[2].find("touch or cut each other"), std::string::npos) << none[2];
  const std::vector<std::string> registered = unsampledDiscontinuities(*scene, reg);
  ASSERT_EQ(registered.size(), 1u) << testing::PrintToString(registered);
  EXPECT_EQ(registered[0], none[2]);
  std::vector<const BoundaryTermKind*> more = boundaryTermKinds();
  BoundaryTermKind contacts;
  contacts.name = "contacts";
  contacts.samples = {Discontinuity::ContactCurves};
  more.push_back(&contacts);
  EXPECT_TRUE(unsampledDiscontinuities(*scene, reg, more).empty());
}

// ---- gradients against finite differences ------------------------------------------------------

TEST(CameraPose, InteriorTermAlone) {
  ShapeCase c(kPlaneScene, "cameras/0/translation", {0.05f, -0.04f, 0.1f});
  for (size_t k : {size_t(0), size_t(2)}) {
    const std::string what = std::string("plane, camera translation ") + "xyz"[k];
    const MeanSE fd = test::validatedFd(c, k, 0.01f, what.c_str());
    const Check r = test::runToPower(c, k, fd, cameraOptions(GradientMethod::Pt), (what + ", pt").c_str());
    test::expectMatches(r, what.c_str());
    test::expectTermPower(r, what.c_str());
  }
  ShapeCase turned(kPlaneScene, "cameras/0/rotation", {1.f, 0.f, 0.f});
  const MeanSE fd = test::validatedFd(turned, 0, 0.2f, "plane, camera rotation x");
  const Check r = test::runToPower(turned, 0, fd, cameraOptions(GradientMethod::Ris), "plane, camera rotation x, ris");
  test::expectMatches(r, "plane, camera rotation x");
  test::expectTermPower(r, "plane, camera rotation x");
}

TEST(CameraPose, ShadowBorderCarriesTheDerivative) {
  ShapeCase c(kShadowScene, "cameras/0/translation", {0.06f, 0.f, 0.f});
  const MeanSE fd = test::validatedFd(c, 0, 0.02f, "card's shadow, camera translation x");
  GradientOptions noSecondary = cameraOptions(GradientMethod::Pt);
  noSecondary.boundary.secondary = false;
  test::expectTermCarries(c, 0, fd, noSecondary, "card's shadow, camera translation x");
}

// Silhouettes, creases and the shadow under an area light together, the camera off in the
// checked component only (the loss then has a clear slope there). The reference takes the seeds
// its noise needs for 10 % power. Without the primary term (the box's outline) the estimate must
// fail the same comparison.
void boxCase(const char* param, size_t k, float offset, float h, int seeds, GradientMethod method, const char* what) {
  std::vector<float> theta(3, 0.f);
  theta[k] = offset;
  ShapeCase c(kBoxScene, param, theta);
  const MeanSE fd = test::validatedFd(c, k, h, what, seeds);
  const std::string label = std::string(what) + ", " + gradientMethodName(method);
  std::vector<float> approach;
  if (method == GradientMethod::Restir) {  // burn-in steps with the camera further off: reuse across camera poses
    approach.assign(3, 0.f);
    approach[k] = 0.3f * offset;
  }
  test::expectMatches(test::runToPower(c, k, fd, cameraOptions(method), label.c_str(), approach), label.c_str());
  if (method == GradientMethod::Pt) {
    GradientOptions noPrimary = cameraOptions(method);
    noPrimary.boundary.primary = false;
    EXPECT_FALSE(test::run(c, k, fd, noPrimary, 96, (label + " without the primary term").c_str()).agrees()) << label;
  }
}

TEST(CameraPose, BoxTranslationPt) { boxCase("cameras/cam/translation", 0, 0.05f, 0.01f, 8, GradientMethod::Pt, "box, camera x"); }
TEST(CameraPose, BoxTranslationRis) { boxCase("cameras/cam/translation", 2, 0.08f, 0.01f, 8, GradientMethod::Ris, "box, camera z"); }
TEST(CameraPose, BoxRotationPt) { boxCase("cameras/cam/rotation", 2, 1.f, 0.1f, 12, GradientMethod::Pt, "box, camera rotation z"); }
TEST(CameraPose, BoxRotationRis) { boxCase("cameras/cam/rotation", 0, 0.8f, 0.1f, 8, GradientMethod::Ris, "box, camera rotation x"); }
// ReSTIR reuses reservoirs made while the camera stood elsewhere (burn-in steps approach theta).
TEST(CameraPoseDeep, BoxRestir) { boxCase("cameras/cam/rotation", 1, 0.8f, 0.1f, 16, GradientMethod::Restir, "box, camera rotation y"); }

}  // namespace
}  // namespace invr
