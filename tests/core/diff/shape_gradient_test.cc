// Shape gradients of whole gradient-engine steps (interior + primary + secondary boundary terms)
// against finite differences of the converged loss.
//
// Reference (fd): the forward renderer (independent code) at theta +- h with common random
// numbers (the same seeds on both sides), loss mean (I_a - T)(I_b - T) from two independent
// renders, averaged over 16 seeds. Trust: the central difference is computed at h and at h/2 with
// the same seeds and the two must agree within 4 combined SE (Richardson: a curvature or topology
// event inside [theta - h, theta + h] would separate them); h is small next to every feature, so
// no edge changes its silhouette set in between. Estimate: the engine's gradient averaged over
// independent sessions. Check |mean - fd| <= 4 sqrt(se^2 + se_fd^2), with power 4 SE <= 30 % of
// |fd|. Ablations run the same comparison with one term switched off and must fail it.
#include <gtest/gtest.h>

#include <filesystem>
#include <tbb/task_arena.h>

#include <array>
#include <chrono>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <tuple>

#include "core/io/mesh_io.h"
#include "core/diff/edge_reservoir_boundary.h"
#include "core/diff/gradient_engine.h"
#include "core/diff/primary_boundary.h"
#include "core/diff/gradient_job_check.h"
#include "core/error.h"
#include "core/render/renderer.h"
#include "core/scene/zoo.h"
#include "core/stopwatch.h"
#include "core/diff/parameter_kind.h"
#include "shared_reference.h"
#include "test_util.h"
#include "core/diff/visibility_case.h"

namespace invr {
namespace {

// A counter the edge-first area-light term keeps of its own (0 when the term did not run).
uint64_t edgeCounter(const invr::v1::GradientStats& st, const std::string& name) {
  auto term = st.boundary().find("area_shadows_edge_first");
  if (term == st.boundary().end()) return 0;
  auto c = term->second.counters().find(name);
  return c == term->second.counters().end() ? 0 : c->second;
}

using test::kSigmas;
using test::MeanSE;
using test::ShapeCase;
using test::Check;
using test::ReferenceSettings;
using test::shapeOptions;
using test::validatedFd;
using test::report;
using test::run;
using test::runToPower;
using test::expectMatches;
using test::expectTermPower;
using test::expectTermCarries;

// A square card between a light and a floor, and a box standing on the floor; the camera looks
// down at the floor. The card is either in view (card, its shadow and both borders) or out of it,
// close under the light (only its shadow is seen). %s: the card's transform, the lamp's shape when
// the light is an area light, the light.
const char* kCardTemplate = R"({
  "materials": [{"name": "grey", "diffuse": {"albedo": {"constant": {"r": 0.6, "g": 0.5, "b": 0.4}}}},
                {"name": "white", "diffuse": {"albedo": {"constant": {"r": 0.8, "g": 0.8, "b": 0.8}}}}],
  "shapes": [
    {"name": "floor", "quad": {}, "material": "grey", "transform": {"scale": {"x": 4, "y": 4, "z": 1}}},
    {"name": "card", "quad": {}, "material": "white", "transform": %s},
    {"name": "box", "box": {}, "material": "white",
     "transform": {"scale": {"x": 0.2, "y": 0.2, "z": 0.2}, "rotate_xyz_degrees": {"z": 30}, "translate": {"x": -0.6, "y": 0.6, "z": 0.2}}}
    %s],
  "groups": [{"name": "props", "shapes": ["card", "box"]}],
  "lights": [%s],
  "views": [{"eye": {"z": 4}, "target": {}, "up": {"y": 1}, "fov_y_degrees": 40}],
  "film": {"width": 40, "height": 40}})";

const char* kPointLight = R"({"name": "bulb", "point": {"position": {"x": 1.2, "y": -0.3, "z": 4}, "intensity": {"r": 12, "g": 12, "b": 12}}})";
const char* kLampShape =
    R"(, {"name": "lamp", "quad": {}, "material": "white", "transform": {"scale": {"x": 0.15, "y": 0.15, "z": 1}, "rotate_xyz_degrees": {"x": 180}, "translate": {"x": 1.2, "y": -0.3, "z": 4}}})";
const char* kAreaLight = R"({"name": "lamp", "area": {"shape": "lamp", "radiance": {"r": 130, "g": 130, "b": 130}}})";
const char* kSky = R"({"name": "sky", "constant_environment": {"radiance": {"r": 1.5, "g": 1.5, "b": 1.5}}})";
// A dim sky with a sun-like lobe (the zoo's backlit_sky), turned so the sun stands 40° from the
// zenith: drawn by the map's importance sampling.
const char* kSunSky = R"({"name": "sky", "environment": {"rotate_y_degrees": %s, "radiance": {"procedural": {"pattern": "backlit_sky",
  "width": 256, "height": 128, "color_a": {"r": 20, "g": 20, "b": 20}, "color_b": {"r": 0.3, "g": 0.3, "b": 0.35}}}}})";

// Turned about z: an edge (or its shadow) parallel to the pixel grid crosses a whole column of
// pixel borders at once, which puts a kink in the loss every pixel it moves; the h vs h/2 check
// of the reference failed on exactly that until the card was turned.
const char* kCardInView = R"({"scale": {"x": 0.3, "y": 0.3, "z": 1}, "rotate_xyz_degrees": {"z": 17}, "translate": {"x": 0.2, "z": 1.5}})";
const char* kCardOutOfView = R"({"scale": {"x": 0.1, "y": 0.1, "z": 1}, "rotate_xyz_degrees": {"z": 17}, "translate": {"x": 1.0, "y": -0.2, "z": 3}})";

std::string cardScene(bool area, bool inView = true) {
  char buf[4096];
  std::snprintf(buf, sizeof buf, kCardTemplate, inView ? kCardInView : kCardOutOfView, area ? kLampShape : "", area ? kAreaLight : kPointLight);
  return buf;
}

// The card under a constant sky, or the sun-lobe sky turned by `sunTurn` degrees about y: its
// soft shadow (and the box's) on the floor. `card` as above.
std::string skyScene(const char* card, const char* sunTurn = nullptr) {
  char light[1024], buf[4096];
  if (sunTurn) std::snprintf(light, sizeof light, kSunSky, sunTurn);
  std::snprintf(buf, sizeof buf, kCardTemplate, card, "", sunTurn ? light : kSky);
  return buf;
}

// A point light 4 degrees above the floor, and a low card out of view standing in its way, turned
// 3 degrees in its own plane: its top edge's shadow crosses the floor the camera sees, at right
// angles to the light, and moves along the floor as the card rises: the whole derivative. The
// renderer draws that border where shadow rays that start an offset above the floor pass the
// edge, which moves it along the floor by the offset times cot 4 degrees (14 offsets).
const char* kGrazingLightScene = R"({
  "materials": [{"name": "grey", "diffuse": {"albedo": {"constant": {"r": 0.6, "g": 0.5, "b": 0.4}}}},
                {"name": "white", "diffuse": {"albedo": {"constant": {"r": 0.8, "g": 0.8, "b": 0.8}}}}],
  "shapes": [
    {"name": "floor", "quad": {}, "material": "grey", "transform": {"scale": {"x": 8, "y": 8, "z": 1}}},
    {"name": "card", "quad": {}, "material": "white",
     "transform": {"scale": {"x": 0.1, "y": 0.3, "z": 1}, "rotate_xyz_degrees": {"z": 3, "y": 90}, "translate": {"x": 3, "y": 0.05, "z": 0.12}}}],
  "lights": [{"name": "bulb", "point": {"position": {"x": 6, "y": 0.1, "z": 0.42}, "intensity": {"r": 400, "g": 400, "b": 400}}}],
  "views": [{"eye": {"z": 4}, "target": {}, "up": {"y": 1}, "fov_y_degrees": 40}],
  "film": {"width": 40, "height": 40}})";

TEST(ShapeGradient, ShadowBorderUnderAGrazingLight) {
  ShapeCase c(kGrazingLightScene, "shapes/card/translation", {0.f, 0.f, 0.004f});
  const MeanSE fd = validatedFd(c, 2, 0.001f, "card z out of view, point light 4 degrees above the floor");
  const Check r = runToPower(c, 2, fd, shapeOptions(GradientMethod::Pt), "grazing light, pt");
  expectMatches(r, "grazing light, pt");
}

// The grazing-light case with the light at 15, 7.6 and 4 degrees above the floor (the card scaled
// so its top edge's shadow stays in view), each against a reference at h = 5e-4 over 32 seeds,
// 1280 sessions each, with the power to see a 10 % error. Before the border term took its pixel
// at the border the renderer draws (shadow_border.h), the estimate was 1.1 %, 1.8 % and 6.3 %
// low, growing with cot(elevation) (docs/shapes.md).
TEST(ShapeGradientDeep, ShadowBorderUnderAGrazingLightAtEachElevation) {
  for (auto [zl, half, tz] : {std::tuple{1.6f, 0.42f, 0.44f}, std::tuple{0.8f, 0.21f, 0.22f}, std::tuple{0.42f, 0.1f, 0.12f}}) {
    std::string json = kGrazingLightScene;
    auto replace = [&](const std::string& from, const std::string& to) { json.replace(json.find(from), from.size(), to); };
    replace("\"z\": 0.42}", "\"z\": " + std::to_string(zl) + "}");
    replace("\"x\": 0.1, \"y\": 0.3", "\"x\": " + std::to_string(half) + ", \"y\": 0.3");
    replace("\"z\": 0.12}", "\"z\": " + std::to_string(tz) + "}");
    char what[96];
    std::snprintf(what, sizeof what, "light %.1f degrees above the floor", std::atan(zl / 6.0) * 180.0 / 3.14159265358979);
    ShapeCase c(json, "shapes/card/translation", {0.f, 0.f, 0.004f});
    const MeanSE fd = validatedFd(c, 2, 0.0005f, what, 32);
    const Check r = run(c, 2, fd, shapeOptions(GradientMethod::Pt), 1280, what);
    std::printf("%s: estimate / reference - 1 = %+.1f %% (%.1f combined SE)\n", what, 100 * (r.est.mean / fd.mean - 1),
                (r.est.mean - fd.mean) / r.combined());
    expectMatches(r, what);
  }
}

TEST(ShapeGradient, CardMovingUnderAPointLight) {
  ShapeCase c(cardScene(false), "shapes/card/translation", {0.08f, -0.05f, 0.1f});
  const MeanSE fdX = validatedFd(c, 0, 0.01f, "card x, point light");
  for (GradientMethod m : {GradientMethod::Pt, GradientMethod::Ris, GradientMethod::Restir})
    expectMatches(runToPower(c, 0, fdX, shapeOptions(m), gradientMethodName(m)), gradientMethodName(m));
  // Stratified samples: the interior passes and the primary and shadow-border terms' samples.
  GradientOptions sobol = shapeOptions(GradientMethod::Pt);
  sobol.sampler = SamplerKind::Sobol;
  expectMatches(runToPower(c, 0, fdX, sobol, "pt, sobol samples"), "pt, sobol samples");
  // Ablation: without the primary term the silhouette's share is missing.
  GradientOptions noPrimary = shapeOptions(GradientMethod::Pt);
  noPrimary.boundary.primary = false;
  EXPECT_FALSE(run(c, 0, fdX, noPrimary, 96, "pt without the primary term").agrees());
}

TEST(ShapeGradient, CardMovingInDepth) {
  // Interior (distance to the light) and both boundaries.
  ShapeCase c(cardScene(false), "shapes/card/translation", {0.08f, -0.05f, 0.1f});
  const MeanSE fdZ = validatedFd(c, 2, 0.01f, "card z, point light", 8);
  expectMatches(runToPower(c, 2, fdZ, shapeOptions(GradientMethod::Ris), "ris, card z"), "ris, card z");
}

TEST(ShapeGradient, ShadowOfAnOccluderOutOfView) {
  // Only the shadow moves on screen: the secondary term is the whole derivative.
  for (bool area : {false, true}) {
    ShapeCase c(cardScene(area, false), "shapes/card/translation", {0.08f, -0.05f, 0.1f});
    const char* what = area ? "card out of view, area light, x" : "card out of view, point light, x";
    // The hard shadow of a card this close to the light moves 4.4 times as fast as the card: a
    // smaller step keeps the curvature of the loss out of the difference.
    const MeanSE fd = validatedFd(c, 0, area ? 0.01f : 0.004f, what, area ? 4 : 8);
    expectMatches(runToPower(c, 0, fd, shapeOptions(GradientMethod::Pt), what), what);
    GradientOptions noSecondary = shapeOptions(GradientMethod::Pt);
    noSecondary.boundary.secondary = false;
    EXPECT_FALSE(run(c, 0, fd, noSecondary, 96, "pt without the secondary term").agrees()) << what;
  }
}

TEST(ShapeGradient, CardMovingUnderASmallAreaLight) {
  ShapeCase c(cardScene(true), "shapes/card/translation", {0.08f, -0.05f, 0.1f});
  const MeanSE fdX = validatedFd(c, 0, 0.01f, "card x, area light");
  for (GradientMethod m : {GradientMethod::Pt, GradientMethod::Ris})
    expectMatches(runToPower(c, 0, fdX, shapeOptions(m), gradientMethodName(m)), gradientMethodName(m));
  // Stratified samples, the area light's border points among them (light-point sampling: the
  // default edge-first sampling keeps independent samples for its edge reservoirs).
  GradientOptions sobol = shapeOptions(GradientMethod::Ris);
  sobol.sampler = SamplerKind::Sobol;
  sobol.boundary.areaSampling = BoundaryOptions::AreaSampling::LightPoints;
  expectMatches(runToPower(c, 0, fdX, sobol, "ris, sobol samples"), "ris, sobol samples");
}

// Under an environment the shadow borders are an integral over the sky's directions
// (environment_shadow_boundary.h). The card low over the floor, out of view beside it, so the
// edge of its soft shadow that reaches into the view is the whole derivative (without the
// secondary term the estimate is 0): under a constant sky (directions uniform on the sphere), and
// (the next test) under a map with a sun-like lobe (directions by the map's importance sampling).
// Then the card in view under the constant sky, where all terms add (the shadow's share is about
// 2 % there).
const char* kCardLowBesideTheView = R"({"scale": {"x": 0.5, "y": 0.5, "z": 1}, "rotate_xyz_degrees": {"z": 17}, "translate": {"x": 2.0, "z": 0.4}})";

// The card beside the view under the constant sky, by `method`, with the power `claim`.
void cardBesideTheViewUnderASky(GradientMethod method, int maxSessions, double claim) {
  ShapeCase c(skyScene(kCardLowBesideTheView), "shapes/card/translation", {0.25f, -0.04f, 0.05f});
  const MeanSE fd = validatedFd(c, 0, 0.01f, "card beside the view, sky, x", 16);
  GradientOptions o = shapeOptions(method);
  o.boundary.samples = 8192;
  o.boundary.lightPoints = 64;
  const std::string what = std::string("card beside the view, sky, ") + gradientMethodName(method);
  expectMatches(runToPower(c, 0, fd, o, what.c_str(), {}, 1.0, maxSessions, claim), what.c_str(), claim);
  if (method != GradientMethod::Pt) return;
  GradientOptions noSecondary = shapeOptions(GradientMethod::Pt);
  noSecondary.boundary.secondary = false;
  EXPECT_FALSE(run(c, 0, fd, noSecondary, 96, "pt without the secondary term").agrees());
}

// 60-80 s: the sky's soft shadow reaches every floor pixel, so the reference (16 seeds) covers the
// whole film, and PT needs its 2048 sessions for 8 %.
// ReSTIR beside the view is the deep suite's (ShapeGradientDeep.RestirShadowsUnderAConstantSky):
// its sessions of three steps (8192 border samples each) cost about 40 ms, and 10 % takes 2048 of
// them, about 90 s.
TEST(ShapeGradient, ShadowsUnderEnvironments) { cardBesideTheViewUnderASky(GradientMethod::Pt, 2048, 0.10); }

TEST(ShapeGradient, ShadowsUnderEnvironmentsInView) {
  ShapeCase c(skyScene(kCardInView), "shapes/card/translation", {0.08f, -0.05f, 0.1f});
  const MeanSE fd = validatedFd(c, 0, 0.01f, "card in view, sky, x");
  for (GradientMethod m : {GradientMethod::Ris, GradientMethod::Restir})
    expectMatches(runToPower(c, 0, fd, shapeOptions(m), gradientMethodName(m)), gradientMethodName(m));
}

// The sun on the card's side (+x), so its sharper shadow falls into the view. The environment's
// border term is the whole derivative here (the card is out of view), and this comparison can
// tell a 10 % error in it.
TEST(ShapeGradient, ShadowsUnderASunLobeSkyMap) {
  ShapeCase c(skyScene(kCardLowBesideTheView, "40"), "shapes/card/translation", {0.25f, -0.04f, 0.05f});
  const MeanSE fd = validatedFd(c, 0, 0.01f, "card beside the view, sun-lobe sky map, x");
  GradientOptions o = shapeOptions(GradientMethod::Pt);
  o.boundary.samples = 8192;
  o.boundary.lightPoints = 64;
  const Check r = runToPower(c, 0, fd, o, "pt, sky map");
  expectMatches(r, "pt, sky map");
  expectTermPower(r, "pt, sky map");
}

// ReSTIR while the shape moves: the reused reservoirs were created 0.06 and 0.03 back along x, so
// near the moving shadow their samples' support differs from the current geometry's. The default
// tests it where each was created (§3.2); the multi-view shortcut tests it here (biased).
TEST(ShapeGradient, RestirReusesSamplesCreatedInEarlierGeometry) {
  ShapeCase c(cardScene(true), "shapes/card/translation", {0.08f, -0.05f, 0.1f});
  const MeanSE fdX = validatedFd(c, 0, 0.01f, "card x, area light");
  const std::vector<float> approach{0.03f, 0.f, 0.f};
  expectMatches(runToPower(c, 0, fdX, shapeOptions(GradientMethod::Restir), "restir after moves", approach), "restir after moves");
  // The shortcut tests reused samples' support in the current geometry: biased while the card
  // moves. Its bias is small against one estimate's noise here (only samples near the moving shadow
  // are affected), so it is measured on the same sessions as the default test: their difference.
  GradientOptions shortcut = shapeOptions(GradientMethod::Restir);
  shortcut.boundary.multiViewShortcut = true;
  const MeanSE diff = c.pairedDifference(0, shortcut, shapeOptions(GradientMethod::Restir), 96, approach);
  std::printf("restir after moves: the shortcut minus the default %+.4e (se %.1e), %.1f %% of the derivative\n", diff.mean, diff.se(),
              100 * diff.mean / fdX.mean);
  EXPECT_GT(std::abs(diff.mean), kSigmas * diff.se()) << "the shortcut's bias should show on the same sessions";
}

// Every way the area light's shadow borders are sampled, where the secondary term is the whole
// derivative: light points first (area_shadow_boundary.h) and edge points first
// (edge_reservoir_boundary.h) with plain light sampling (pt), RIS, and ReSTIR's edge reservoirs
// reused across steps while the card moves (edge importance on and off, and neighbours merged).
TEST(ShapeGradient, AreaLightShadowBordersEverySampling) {
  ShapeCase c(cardScene(true, false), "shapes/card/translation", {0.08f, -0.05f, 0.1f});
  const MeanSE fd = validatedFd(c, 0, 0.01f, "card out of view, area light, x");
  const std::vector<float> approach{0.02f, 0.f, 0.f};
  GradientOptions lightPoints = shapeOptions(GradientMethod::Ris);
  lightPoints.boundary.areaSampling = BoundaryOptions::AreaSampling::LightPoints;
  expectMatches(runToPower(c, 0, fd, lightPoints, "ris, light points first"), "ris, light points first");
  expectMatches(runToPower(c, 0, fd, shapeOptions(GradientMethod::Pt), "pt, edge first"), "pt, edge first");
  expectMatches(runToPower(c, 0, fd, shapeOptions(GradientMethod::Ris), "ris, edge first"), "ris, edge first");
  expectMatches(runToPower(c, 0, fd, shapeOptions(GradientMethod::Restir), "restir, edge reservoirs", approach), "restir, edge reservoirs");
  GradientOptions noImportance = shapeOptions(GradientMethod::Restir);
  noImportance.boundary.term<EdgeFirstAreaShadowOptions>().edgeImportance = false;
  expectMatches(runToPower(c, 0, fd, noImportance, "restir, no edge importance", approach), "restir, no edge importance");
  GradientOptions merged = shapeOptions(GradientMethod::Restir);
  merged.boundary.term<EdgeFirstAreaShadowOptions>().edgeNeighbours = 3;  // kd-tree neighbours merged, supports tested where they were made
  expectMatches(runToPower(c, 0, fd, merged, "restir, 3 edge neighbours", approach), "restir, 3 edge neighbours");
  GradientOptions forwardOnly = shapeOptions(GradientMethod::Restir);
  forwardOnly.forwardOnly = true;
  expectMatches(runToPower(c, 0, fd, forwardOnly, "forward-only"), "forward-only");
}

// The tree's lighting (Wang et al. 2023, Fig. 9): besides the small lamp, a larger lamp with twice
// its power hidden behind a board from everything below it. None of its light points casts a
// border, which the edge-first target sees through its visibility ray (h = 0, the support
// unchanged): the estimate must stay unbiased with hidden candidates in the reservoirs, merged
// neighbours included. (Unbiasedness only: any h >= 0 gives the same mean.)
TEST(ShapeGradient, AreaLightHiddenBehindABoard) {
  std::string json = cardScene(true, false);
  const std::string lamp = kLampShape;
  json.replace(json.find(lamp), lamp.size(),
               lamp + R"(, {"name": "hidden_lamp", "quad": {}, "material": "white", "transform": {"scale": {"x": 0.4, "y": 0.4, "z": 1}, "rotate_xyz_degrees": {"x": 180}, "translate": {"x": -1.5, "y": 1.0, "z": 4.5}}},
                  {"name": "board", "quad": {}, "material": "grey", "transform": {"scale": {"x": 0.7, "y": 0.7, "z": 1}, "translate": {"x": -1.5, "y": 1.0, "z": 4.35}}})");
  const std::string light = kAreaLight;
  json.replace(json.find(light), light.size(), light + R"(, {"name": "hidden", "area": {"shape": "hidden_lamp", "radiance": {"r": 37, "g": 37, "b": 37}}})");
  ShapeCase c(json, "shapes/card/translation", {0.08f, -0.05f, 0.1f});
  const MeanSE fd = validatedFd(c, 0, 0.01f, "card out of view, lamp and a hidden lamp, x");
  expectMatches(runToPower(c, 0, fd, shapeOptions(GradientMethod::Ris), "ris, edge first, hidden lamp"), "ris, edge first, hidden lamp");
  expectMatches(runToPower(c, 0, fd, shapeOptions(GradientMethod::Restir), "restir, edge reservoirs, hidden lamp", {0.02f, 0.f, 0.f}),
                "restir, edge reservoirs, hidden lamp");
  GradientOptions merged = shapeOptions(GradientMethod::Restir);
  merged.boundary.term<EdgeFirstAreaShadowOptions>().edgeNeighbours = 3;
  expectMatches(runToPower(c, 0, fd, merged, "restir, 3 edge neighbours, hidden lamp", {0.02f, 0.f, 0.f}), "restir, 3 edge neighbours, hidden lamp");
}

// Merged neighbours must be counted in Z only where their own target (their edge's face normals as
// they were created) could have produced the chosen light point. On a card every neighbour lies on
// the same edge and the test is nearly always true; on a small box out of view under the area
// light, neighbours come from the box's other edges, with other normals, whose silhouettes from the
// lamp differ. Counting them all inflates Z and the estimate comes out low.
TEST(ShapeGradient, MergedEdgeNeighboursAreCountedByTheirOwnSupport) {
  std::string json = cardScene(true, false);
  const std::string card = R"("card", "quad": {})";
  json.replace(json.find(card), card.size(), R"("card", "box": {})");
  const std::string tr = kCardOutOfView;
  json.replace(json.find(tr), tr.size(),
               R"({"scale": {"x": 0.08, "y": 0.08, "z": 0.08}, "rotate_xyz_degrees": {"x": 25, "z": 17}, "translate": {"x": 1.0, "y": -0.2, "z": 3}})");
  ShapeCase c(json, "shapes/card/translation", {0.06f, -0.04f, 0.05f});
  const MeanSE fd = validatedFd(c, 0, 0.01f, "box out of view, area light, x");
  GradientOptions merged = shapeOptions(GradientMethod::Restir);
  merged.boundary.term<EdgeFirstAreaShadowOptions>().edgeNeighbours = 8;
  expectMatches(runToPower(c, 0, fd, merged, "restir, 8 edge neighbours", {0.02f, 0.f, 0.f}), "restir, 8 edge neighbours");
}

// Alg. 6 keeps one edge reservoir per sample; Alg. 8 adds the previous step's reservoirs whose p1
// the step's views do not see, never when the step holds every view of the session, and drops them
// after EdgeReservoirBoundary::kMaxAge steps.
TEST(ShapeGradient, EdgeReservoirsAreKeptAndUnseenOnesPreserved) {
  ShapeCase c(cardScene(true, false), "shapes/card/translation", {0.08f, -0.05f, 0.1f});
  GradientOptions o = shapeOptions(GradientMethod::Restir);
  o.boundary.samples = 256;
  GradientEngine engine(*c.scene, c.reg, {c.target}, o);
  for (bool all : {false, true}) {
    EngineSession session;
    GradientRequest r;
    r.views = {0};
    r.allSessionViews = all;
    size_t most = 0;
    for (uint64_t step = 0; step < 12; ++step) {
      r.step = step;
      const invr::v1::GradientStats st = engine.evaluate(r, session).stats;
      EXPECT_EQ(edgeCounter(st, "edge_reservoirs"), 256u + edgeCounter(st, "edge_reservoirs_preserved")) << "step " << step;
      ASSERT_NE(keptEdgeReservoirs(session.boundary), nullptr);
      EXPECT_EQ(keptEdgeReservoirs(session.boundary)->items.size(), edgeCounter(st, "edge_reservoirs"));
      if (step == 0 || all) {
        EXPECT_EQ(edgeCounter(st, "edge_reservoirs_preserved"), 0u) << "step " << step;
      }
      if (step == 1 && !all) {
        EXPECT_GT(edgeCounter(st, "edge_reservoirs_preserved"), 0u);  // shadows falling off the film, or hidden
      }
      most = std::max(most, edgeCounter(st, "edge_reservoirs_preserved"));
    }
    EXPECT_LE(most, size_t(EdgeReservoirBoundary::kMaxAge - 1) * 256u);
  }
  GradientOptions pt = shapeOptions(GradientMethod::Pt);
  GradientEngine ptEngine(*c.scene, c.reg, {c.target}, pt);
  EngineSession session;
  GradientRequest r;
  r.views = {0};
  EXPECT_EQ(edgeCounter(ptEngine.evaluate(r, session).stats, "edge_reservoirs"), 0u);  // nothing to reuse
  EXPECT_TRUE(!keptEdgeReservoirs(session.boundary) || keptEdgeReservoirs(session.boundary)->items.empty());
}

TEST(ShapeGradient, ReceiverMovingUnderAPointLight) {
  // The floor rises: its shading (distance to the light) and the card's shadow on it change.
  ShapeCase c(cardScene(false), "shapes/floor/translation", {0.f, 0.f, 0.15f});
  const MeanSE fd = validatedFd(c, 2, 0.01f, "floor z, point light");
  expectMatches(runToPower(c, 2, fd, shapeOptions(GradientMethod::Pt), "pt, floor z"), "pt, floor z");
}

TEST(ShapeGradient, BoxRotationShowsItsCreases) {
  ShapeCase c(cardScene(false), "shapes/box/rotation", {0.f, 0.f, 8.f});
  const MeanSE fd = validatedFd(c, 2, 0.5f, "box rotation z", 48);
  expectMatches(runToPower(c, 2, fd, shapeOptions(GradientMethod::Ris), "ris, box rotation z"), "ris, box rotation z");
}

TEST(ShapeGradient, GroupRotation) {
  ShapeCase c(cardScene(true), "groups/props/rotation", {0.f, 0.f, 6.f});
  const MeanSE fd = validatedFd(c, 2, 0.5f, "group rotation z, area light");
  expectMatches(runToPower(c, 2, fd, shapeOptions(GradientMethod::Pt), "pt, group rotation z"), "pt, group rotation z");
}

// A large plane filling the view under a point light: no silhouette, crease or shadow moves on
// the film, so the interior shape term (the hit sliding along the fixed camera ray, the normal
// turning) is the whole derivative. Moving in depth (distance to the light) and tilting (the
// normal's part).
const char* kPlaneScene = R"({
  "materials": [{"name": "grey", "diffuse": {"albedo": {"constant": {"r": 0.6, "g": 0.5, "b": 0.4}}}}],
  "shapes": [{"name": "plane", "quad": {}, "material": "grey", "transform": {"scale": {"x": 4, "y": 4, "z": 1}}}],
  "lights": [{"name": "bulb", "point": {"position": {"x": 0.9, "y": -0.4, "z": 1.6}, "intensity": {"r": 6, "g": 6, "b": 6}}}],
  "views": [{"eye": {"z": 4}, "target": {}, "up": {"y": 1}, "fov_y_degrees": 40}],
  "film": {"width": 40, "height": 40}})";

TEST(ShapeGradient, InteriorTermAlone) {
  {
    ShapeCase c(kPlaneScene, "shapes/plane/translation", {0.f, 0.f, 0.1f});
    const MeanSE fd = validatedFd(c, 2, 0.004f, "plane z (interior only)");
    for (GradientMethod m : {GradientMethod::Pt, GradientMethod::Ris}) {
      const Check r = runToPower(c, 2, fd, shapeOptions(m), (std::string("plane z, ") + gradientMethodName(m)).c_str());
      expectMatches(r, "plane z");
      expectTermPower(r, "plane z");
    }
  }
  ShapeCase c(kPlaneScene, "shapes/plane/rotation", {4.f, 0.f, 0.f});
  const MeanSE fd = validatedFd(c, 0, 0.5f, "plane tilting about x (interior only)");
  const Check r = runToPower(c, 0, fd, shapeOptions(GradientMethod::Pt), "plane rotation x, pt");
  expectMatches(r, "plane rotation x");
  expectTermPower(r, "plane rotation x");
}

// A box seen close up at the edge between its top and front faces, which a point light shades
// differently: the crease is the only boundary on the film (the box's outline is outside it), and
// moving the box towards the camera slides the crease across the film. The interior term is small
// here (the light is far); its share is printed and taken off the power the test demands.
const char* kCreaseScene = R"({
  "materials": [{"name": "white", "diffuse": {"albedo": {"constant": {"r": 0.8, "g": 0.8, "b": 0.8}}}}],
  "shapes": [{"name": "box", "box": {}, "material": "white", "transform": {"scale": {"x": 2, "y": 2, "z": 2}}}],
  "lights": [{"name": "bulb", "point": {"position": {"x": 3, "y": -12, "z": 20}, "intensity": {"r": 600, "g": 600, "b": 600}}}],
  "views": [{"eye": {"x": 0.1, "y": -5, "z": 5}, "target": {"x": 0.1, "y": -2, "z": 2}, "up": {"z": 1}, "fov_y_degrees": 15}],
  "film": {"width": 40, "height": 40}})";

TEST(ShapeGradient, CreaseTermAlone) {
  ShapeCase c(kCreaseScene, "shapes/box/translation", {0.f, 0.05f, 0.f});
  const MeanSE fd = validatedFd(c, 1, 0.01f, "box y, crease in view");
  GradientOptions interior = shapeOptions(GradientMethod::Pt);
  interior.boundary.primary = interior.boundary.secondary = false;
  expectTermCarries(c, 1, fd, interior, "box y, crease, pt");
}

// Shallow creases: a flat-shaded 24-sided cylinder (adjacent faces 15 degrees apart, so each
// crease's jump bound |n0 - n1| is 0.26) seen close up from its side, tilted so its creases cross
// the pixel grid at a slant, its outline and rims off the film, under a point light. Moving it
// sideways slides the creases across the film: the primary term's crease samples, weighted by
// that bound, carry nearly all of the derivative (the share is measured). Dividing a sample by 1
// instead of its bound (the weighting's pdf left out) must fail here.
const char* kShallowCreaseScene = R"({
  "materials": [{"name": "white", "diffuse": {"albedo": {"constant": {"r": 0.8, "g": 0.8, "b": 0.8}}}}],
  "shapes": [{"name": "drum", "cylinder": {"segments": 24}, "face_normals": true, "material": "white",
              "transform": {"scale": {"x": 1, "y": 1, "z": 3}, "rotate_xyz_degrees": {"y": 12, "z": 4}}}],
  "lights": [{"name": "bulb", "point": {"position": {"x": -6, "y": -8, "z": 3}, "intensity": {"r": 200, "g": 200, "b": 200}}}],
  "views": [{"eye": {"x": 0.05, "y": -4, "z": 0.3}, "target": {"x": 0.05, "y": -1, "z": 0.3}, "up": {"z": 1}, "fov_y_degrees": 15}],
  "film": {"width": 40, "height": 40}})";

TEST(ShapeGradient, ShallowCreasesCarryTheDerivative) {
  ShapeCase c(kShallowCreaseScene, "shapes/drum/translation", {0.04f, 0.f, 0.f});
  // Every crease (the open drum's rims are boundary edges, its quads' diagonals no creases) is
  // between two sides 15 degrees apart.
  const std::vector<Vec3>& n = c.scene->meshes[0].faceNormals;
  const EdgeTopology topology = EdgeTopology::build(c.scene->meshes[0]);
  for (const MeshEdge& e : topology.edges()) {
    if (e.crease && !e.boundary()) {
      EXPECT_NEAR(PrimaryBoundary::creaseJumpBound(n[e.face0], n[e.face1]), 0.261f, 0.002f);
    }
  }
  const MeanSE fd = validatedFd(c, 0, 0.004f, "drum x, shallow creases in view");
  GradientOptions interior = shapeOptions(GradientMethod::Pt);
  interior.boundary.primary = interior.boundary.secondary = false;
  expectTermCarries(c, 0, fd, interior, "drum x, shallow creases, pt");
}

// The card out of view moving along z, towards its shadow's receiver: the occluder's velocity has
// a component along the receiver's normal, the part of the border gradient, -c n_r, that sideways
// motion over a z-up floor never exercises. The point light's border is the whole derivative.
TEST(ShapeGradient, OccluderMovingAlongTheReceiverNormal) {
  ShapeCase c(cardScene(false, false), "shapes/card/translation", {0.08f, -0.05f, 0.1f});
  const MeanSE fd = validatedFd(c, 2, 0.004f, "card out of view, point light, z", 64);
  const Check r = runToPower(c, 2, fd, shapeOptions(GradientMethod::Pt), "card out of view, point light, z");
  expectMatches(r, "card out of view z");
  expectTermPower(r, "card out of view z");
}

// The receiver moving along its own normal under a static card: the part of the border gradient
// that moves with the receiver, (c n_r) . u_k, alone and with the power to see a 10 % error in it
// (in ReceiverMovingUnderAPointLight the floor's shading carries most of the derivative). The
// point light is far, so the floor's shading hardly changes with its height (the interior term is
// small) while the slanted light slides the card's shadow sideways as the floor rises. No box
// stands on the floor, whose contact curve no term samples.
const char* kRisingFloorScene = R"({
  "materials": [{"name": "grey", "diffuse": {"albedo": {"constant": {"r": 0.6, "g": 0.5, "b": 0.4}}}},
                {"name": "white", "diffuse": {"albedo": {"constant": {"r": 0.8, "g": 0.8, "b": 0.8}}}}],
  "shapes": [
    {"name": "floor", "quad": {}, "material": "grey", "transform": {"scale": {"x": 4, "y": 4, "z": 1}}},
    {"name": "card", "quad": {}, "material": "white",
     "transform": {"scale": {"x": 0.3, "y": 0.3, "z": 1}, "rotate_xyz_degrees": {"z": 17}, "translate": {"x": 0.2, "y": 0.1, "z": 0.8}}}],
  "lights": [{"name": "bulb", "point": {"position": {"x": 20, "y": -8, "z": 40}, "intensity": {"r": 1500, "g": 1500, "b": 1500}}}],
  "views": [{"eye": {"z": 4}, "target": {}, "up": {"y": 1}, "fov_y_degrees": 40}],
  "film": {"width": 40, "height": 40}})";

TEST(ShapeGradient, ReceiverMovingAlongItsNormal) {
  ShapeCase c(kRisingFloorScene, "shapes/floor/translation", {0.f, 0.f, 0.1f});
  const MeanSE fd = validatedFd(c, 2, 0.01f, "floor z under a static card", 16);
  GradientOptions noBorders = shapeOptions(GradientMethod::Pt);
  noBorders.boundary.secondary = false;
  expectTermCarries(c, 2, fd, noBorders, "floor z, pt");
}

// Occluder and receiver moving together (one group), as on the knot, whose tube shadows itself:
// both parts of the border gradient at once. They move along the floor's normal, so each part is
// large (c n_r . u, from the receiver and, times -s, from the occluder) and they nearly cancel:
// dropping either fails. (Sideways over the floor both would be 0.) The card is out of view and
// only its shadow is seen, so the border term is the whole derivative.
TEST(ShapeGradient, OccluderAndReceiverMovingTogether) {
  std::string json = kRisingFloorScene;
  const std::string lights = R"(  "lights")", card = R"("translate": {"x": 0.2, "y": 0.1, "z": 0.8})";
  json.replace(json.find(lights), lights.size(), R"(  "groups": [{"name": "both", "shapes": ["floor", "card"]}],
  "lights")");
  json.replace(json.find(card), card.size(), R"("translate": {"x": 1.9, "y": -0.2, "z": 1.6})");
  ShapeCase c(json, "groups/both/translation", {0.f, 0.f, 0.1f});
  const MeanSE fd = validatedFd(c, 2, 0.01f, "card and floor z", 64);
  GradientOptions noBorders = shapeOptions(GradientMethod::Pt);
  noBorders.boundary.secondary = false;
  expectTermCarries(c, 2, fd, noBorders, "card and floor z, pt", 256);
}

// Edge reservoirs reused while the occluder turns: the normals of a reservoir's edge faces change
// between the step it was made in and the step that reuses it, so whether its edge was a
// silhouette from a light point (its support) must be judged with the normals it was made with. A
// small box out of view (its edges have two faces, unlike a card's) swings about a pivot below it
// (its shadow slides, its faces turn) 5 degrees a step before the measured one; ReSTIR merges 8
// edge neighbours per sample, so the support of each is tested.
TEST(ShapeGradient, EdgeReservoirsMadeBeforeARotation) {
  std::string json = cardScene(true, false);
  const std::string card = R"("name": "card", "quad": {})";
  json.replace(json.find(card), card.size(), R"("name": "card", "pivot": {"x": 1.0, "y": -0.2, "z": 2.0}, "box": {})");
  const std::string tr = kCardOutOfView;
  json.replace(json.find(tr), tr.size(),
               R"({"scale": {"x": 0.08, "y": 0.08, "z": 0.08}, "rotate_xyz_degrees": {"x": 25, "z": 17}, "translate": {"x": 1.0, "y": -0.2, "z": 3}})");
  ShapeCase c(json, "shapes/card/rotation", {0.f, 4.f, 0.f});
  const MeanSE fd = validatedFd(c, 1, 0.25f, "box out of view, area light, swinging about y");
  GradientOptions o = shapeOptions(GradientMethod::Restir);
  o.boundary.samples = 2048;
  o.boundary.term<EdgeFirstAreaShadowOptions>().edgeNeighbours = 8;
  const Check r = runToPower(c, 1, fd, o, "restir, 8 edge neighbours made 5 and 10 degrees back", {0.f, 5.f, 0.f});
  expectMatches(r, "restir after a rotation");
  expectTermPower(r, "restir after a rotation");
}

// The zoo's knot (Wang et al. 2023, Figs. 6-7) at a small film: a flat-shaded torus knot whose
// many silhouette edges cast shadows under a bright spot and two dim point fills (delta lights
// only, so every shadow border goes to delta_shadow_boundary). `Fills` drops the spot and
// brightens the fills, so the point lights' borders carry the derivative; `BesideCamera` keeps one
// of them, moved 0.5 right of and 0.4 above the eye (0, 1.2, 3.0), where the knot's shadows on
// itself are thin. `FrontFill` and `BackFill` keep one fill where it is: fill_a in front of the
// knot at its side, fill_b behind it.
enum class KnotLights { SpotAndFills, Fills, BesideCamera, FrontFill, BackFill };

std::unique_ptr<Scene> knotScene(KnotLights lights, bool floor = true) {
  invr::v1::Scene s = zooScene("knot");
  s.mutable_film()->set_width(64);
  s.mutable_film()->set_height(48);
  invr::v1::Scene kept = s;
  kept.clear_shapes();
  for (const auto& sh : s.shapes())
    if (floor || sh.name() != "floor") *kept.add_shapes() = sh;
  if (lights != KnotLights::SpotAndFills) {
    kept.clear_lights();
    for (const auto& l : s.lights()) {
      if (l.has_spot()) continue;
      if ((lights == KnotLights::FrontFill && l.name() != "fill_a") || (lights == KnotLights::BackFill && l.name() != "fill_b")) continue;
      auto* p = kept.add_lights();
      *p = l;
      auto* i = p->mutable_point()->mutable_intensity();
      i->set_r(i->r() * 12);
      i->set_g(i->g() * 12);
      i->set_b(i->b() * 12);
      if (lights == KnotLights::BesideCamera) {
        auto* at = p->mutable_point()->mutable_position();
        at->set_x(0.5);
        at->set_y(1.6);
        at->set_z(3.0);
        break;
      }
    }
  }
  return buildScene(kept);
}
std::string knotId(KnotLights lights, bool floor = true) {
  return "zoo knot at 64x48, lights " + std::to_string(int(lights)) + (floor ? ", floor" : ", no floor");
}

TEST(ShapeGradient, KnotUnderASpotAndPointFills) {
  ShapeCase c(knotScene(KnotLights::SpotAndFills), "shapes/knot/translation", {0.06f, -0.04f, 0.05f}, knotId(KnotLights::SpotAndFills));
  const MeanSE fd = validatedFd(c, 0, 0.005f, "knot x, spot and fills", 8);
  GradientOptions pt = shapeOptions(GradientMethod::Pt);
  pt.boundary.samples = 32768;
  expectMatches(runToPower(c, 0, fd, pt, "knot x, pt"), "knot x, pt");
  for (GradientMethod m : {GradientMethod::Ris, GradientMethod::Restir}) {
    GradientOptions o = shapeOptions(m);
    o.boundary.samples = 4096;
    const std::string what = std::string("knot x, ") + gradientMethodName(m);
    expectMatches(runToPower(c, 0, fd, o, what.c_str(), {0.01f, 0.f, 0.f}), what.c_str());
  }
  GradientOptions forwardOnly = shapeOptions(GradientMethod::Restir);
  forwardOnly.boundary.samples = 4096;
  forwardOnly.forwardOnly = true;
  expectMatches(runToPower(c, 0, fd, forwardOnly, "knot x, forward-only"), "knot x, forward-only");
}

// The same knot under the two point fills alone, brightened: the point lights' borders (on the
// floor and on the knot itself) are a tenth of the derivative here.
TEST(ShapeGradient, KnotUnderPointLightsOnly) {
  ShapeCase c(knotScene(KnotLights::Fills), "shapes/knot/translation", {0.06f, -0.04f, 0.05f}, knotId(KnotLights::Fills));
  const MeanSE fd = validatedFd(c, 0, 0.005f, "knot x, point fills");
  for (GradientMethod m : {GradientMethod::Pt, GradientMethod::Restir}) {
    GradientOptions o = shapeOptions(m);
    o.boundary.samples = m == GradientMethod::Pt ? 16384 : 4096;
    const std::string what = std::string("knot x, point fills, ") + gradientMethodName(m);
    expectMatches(runToPower(c, 0, fd, o, what.c_str()), what.c_str());
  }
}

// Diagnosis of the knot's excess (docs/shapes.md, "The knot's excess"): in the
// deep suite (bash deploy/test.sh --deep), which checks each reference (h against h/2) and prints
// FD and the PT estimate with every term and with terms left out, for the point fills with or
// without the floor, for each fill alone where it is, and for one point light beside the camera.
// Sessions per estimate: INVR_KNOT_SESSIONS (default 256; the documented figures used thousands),
// but the front fill alone, which issue 59 names, at 2048 (INVR_KNOT_SESSIONS still overrides it).
// Run them alone with
//   build/bin/test_diff --gtest_filter='ShapeGradientDeep.KnotExcess*'
int knotDiagnosisSessions(int otherwise = 256) {
  const char* v = std::getenv("INVR_KNOT_SESSIONS");
  return v && std::atoi(v) > 0 ? std::atoi(v) : otherwise;
}

void diagnoseKnot(KnotLights lights, bool floor, const char* what, int sessionsOtherwise = 256) {
  ShapeCase c(knotScene(lights, floor), "shapes/knot/translation", {0.06f, -0.04f, 0.05f}, knotId(lights, floor), {1024, false});
  const MeanSE fd = validatedFd(c, 0, 0.005f, what, 64, false);
  const int sessions = knotDiagnosisSessions(sessionsOtherwise);
  std::printf("%d sessions per estimate\n", sessions);
  GradientOptions all = shapeOptions(GradientMethod::Pt);
  all.boundary.samples = 16384;
  const Check r = run(c, 0, fd, all, sessions, "pt, every term");
  std::printf("  difference %+.2f %% (%.1f SE)\n", 100 * (r.est.mean - fd.mean) / fd.mean, (r.est.mean - fd.mean) / r.combined());
  GradientOptions noPrimary = all;
  noPrimary.boundary.primary = false;
  run(c, 0, fd, noPrimary, sessions, "pt, without the primary term");
  GradientOptions noSecondary = all;
  noSecondary.boundary.secondary = false;
  run(c, 0, fd, noSecondary, sessions, "pt, without the border terms");
}

// The knot's excess by pixel class (issue 59): the front fill alone, no floor, each pixel put in
// one class by 4 x 4 camera rays through it: within a pixel of the knot's outline (its 3 x 3
// neighbourhood holds knot and background); holding a terminator crease (knot faces turned to the
// light and away from it); holding a cast border (faces turned to the light, some of their points
// lit and some shadowed); the rest. Or, byWhatTheOutlineHolds, the outline's pixels split by what
// their rays hold (a knot point in a cast shadow; else a face turned from the light; else all lit)
// and all other pixels in one class. Per class the loss over its pixels: its reference (the masked
// loss's central difference, 64 seeds) and the PT estimate with the class as a loss mask; the
// classes' differences add up to the whole's. INVR_KNOT_SESSIONS sessions each (default 256).
std::array<std::vector<float>, 4> knotPixelClasses(const Scene& scene, uint32_t knot, Vec3 light, bool byWhatTheOutlineHolds) {
  const Camera& cam = scene.cameras[0];
  const int W = scene.width, H = scene.height, n = 4;
  std::vector<uint8_t> onKnot(size_t(W) * size_t(H)), offKnot(onKnot.size()), facing(onKnot.size()), turned(onKnot.size()),
      lit(onKnot.size()), shadowed(onKnot.size());
  for (int y = 0; y < H; ++y)
    for (int x = 0; x < W; ++x)
      for (int sy = 0; sy < n; ++sy)
        for (int sx = 0; sx < n; ++sx) {
          const size_t p = size_t(y) * size_t(W) + size_t(x);
          SurfaceHit h;
          if (!scene.intersect(cam.eye, cam.direction(float(x) + (float(sx) + 0.5f) / float(n), float(y) + (float(sy) + 0.5f) / float(n), W, H), h) ||
              h.mesh != knot) {
            offKnot[p] = 1;
            continue;
          }
          onKnot[p] = 1;
          if (!(dot(h.ng, light - h.p) > 0.f)) {
            turned[p] = 1;
            continue;
          }
          facing[p] = 1;
          Vec3 dir;
          float tmax;
          (scene.occludedSegment(Scene::shadowOrigin(h.p, h.ng, light - h.p), light, dir, tmax) ? shadowed : lit)[p] = 1;
        }
  std::array<std::vector<float>, 4> classes;
  for (auto& c : classes) c.assign(size_t(W) * size_t(H), 0.f);
  for (int y = 0; y < H; ++y)
    for (int x = 0; x < W; ++x) {
      const size_t p = size_t(y) * size_t(W) + size_t(x);
      bool on = false, off = false;
      for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx) {
          const int xx = std::clamp(x + dx, 0, W - 1), yy = std::clamp(y + dy, 0, H - 1);
          on = on || onKnot[size_t(yy) * size_t(W) + size_t(xx)];
          off = off || offKnot[size_t(yy) * size_t(W) + size_t(xx)];
        }
      const int k = !byWhatTheOutlineHolds ? (on && off ? 0 : facing[p] && turned[p] ? 1 : lit[p] && shadowed[p] ? 2 : 3)
                                           : (!(on && off) ? 3 : shadowed[p] ? 0 : turned[p] ? 1 : 2);
      classes[size_t(k)][p] = 1.f;
    }
  return classes;
}

void knotExcessByPixelClass(bool byWhatTheOutlineHolds) {
  const char* names[2][4] = {{"within a pixel of the outline", "holding a terminator crease", "holding a cast border", "the rest"},
                             {"at the outline, holding a shadowed knot point", "at the outline, holding a face turned from the light",
                              "at the outline, all lit", "away from the outline"}};
  ShapeCase c(knotScene(KnotLights::FrontFill, false), "shapes/knot/translation", {0.06f, -0.04f, 0.05f}, knotId(KnotLights::FrontFill, false),
              {1024, false});
  ASSERT_EQ(c.scene->lights.size(), 1u);
  const std::array<std::vector<float>, 4> classes =
      knotPixelClasses(*c.scene, c.reg.movingMeshes()[0], c.scene->lights[0].position, byWhatTheOutlineHolds);
  const int sessions = knotDiagnosisSessions();
  const std::string id = c.id + (byWhatTheOutlineHolds ? "|outline by what it holds" : "");
  double sumDiff = 0, sumVar = 0;
  for (size_t k = 0; k < classes.size(); ++k) {
    double pixels = 0;
    for (float w : classes[k]) pixels += w;
    c.pixelWeights = classes[k];
    c.id = id + "|pixel class " + std::to_string(k);
    std::string what = std::string("knot x, front fill, no floor, pixels ") + names[byWhatTheOutlineHolds][k];
    std::printf("%s: %.0f pixels\n", what.c_str(), pixels);
    const MeanSE fd = validatedFd(c, 0, 0.005f, what.c_str(), 64, false);
    GradientOptions o = shapeOptions(GradientMethod::Pt);
    o.boundary.samples = 16384;
    o.lossMasks = {classes[k]};
    const Check r = run(c, 0, fd, o, sessions, what.c_str());
    std::printf("  difference %+.3e (%.1f SE)\n", r.est.mean - fd.mean, (r.est.mean - fd.mean) / r.combined());
    sumDiff += r.est.mean - fd.mean;
    sumVar += r.combined() * r.combined();
    if (byWhatTheOutlineHolds) {  // each class's estimate without a term: what that term carries there
      GradientOptions noPrimary = o, noBorders = o;
      noPrimary.boundary.primary = false;
      noBorders.boundary.secondary = false;
      run(c, 0, fd, noPrimary, sessions, "  without the primary term");
      run(c, 0, fd, noBorders, sessions, "  without the border terms");
    }
  }
  std::printf("knot x, front fill, no floor: the classes' differences add to %+.3e +- %.1e\n", sumDiff, std::sqrt(sumVar));
}

TEST(ShapeGradientDeep, KnotExcessByPixelClass) { knotExcessByPixelClass(false); }
// The same with the outline's pixels split by what their 4 x 4 camera rays hold: a knot point in
// a cast shadow; else a face turned away from the light; else all lit. Each class also without
// the primary and without the border terms.
TEST(ShapeGradientDeep, KnotOutlineExcessByWhatItHolds) { knotExcessByPixelClass(true); }

TEST(ShapeGradientDeep, KnotExcessPointFillsFloor) { diagnoseKnot(KnotLights::Fills, true, "knot x, point fills, floor"); }
TEST(ShapeGradientDeep, KnotExcessPointFillsNoFloor) { diagnoseKnot(KnotLights::Fills, false, "knot x, point fills, no floor"); }
TEST(ShapeGradientDeep, KnotExcessFrontFillNoFloor) { diagnoseKnot(KnotLights::FrontFill, false, "knot x, the front fill alone, no floor", 2048); }
TEST(ShapeGradientDeep, KnotExcessBackFillNoFloor) { diagnoseKnot(KnotLights::BackFill, false, "knot x, the back fill alone, no floor"); }
TEST(ShapeGradientDeep, KnotExcessLightBesideCameraNoFloor) {
  diagnoseKnot(KnotLights::BesideCamera, false, "knot x, one point light beside the camera, no floor");
}

// The primary term's side offsets on the knot (front fill, no floor): the same sessions with the
// offsets of before issue 59 (1e-3 px shrinking to 1e-4 px; on this film the edge point's rounding
// is about 4e-6 px, so 250 and 25 roundings), and 10 and 4 times today's, against today's. Paired,
// so the difference's standard error is the offsets' effect alone; four times today's must move it
// by under 0.1 %. (Below
// one rounding the two sides' rays are the same float ray and the estimate breaks down: 0.4 and
// 0.025 roundings read 2.9e-4, 1.7 %, low.)
TEST(ShapeGradientDeep, KnotPrimarySideOffsets) {
  ShapeCase c(knotScene(KnotLights::FrontFill, false), "shapes/knot/translation", {0.06f, -0.04f, 0.05f}, knotId(KnotLights::FrontFill, false),
              {1024, false});
  const int sessions = knotDiagnosisSessions();
  GradientOptions today = shapeOptions(GradientMethod::Pt);
  today.boundary.samples = 16384;
  for (auto [start, floor] : {std::pair{250.0, 25.0}, std::pair{40.0, 2.5}, std::pair{16.0, 1.0}}) {  // 16: four times today's
    GradientOptions other = today;
    other.boundary.term<PrimaryBoundaryOptions>().sideOffsetRoundings = start;
    other.boundary.term<PrimaryBoundaryOptions>().minSideOffsetRoundings = floor;
    const MeanSE d = c.pairedDifference(0, other, today, sessions, {});
    std::printf("knot x, front fill: primary side offsets from %g down to %g roundings, minus today's (%g down to %g): %+.3e +- %.1e "
                "(%d sessions)\n",
                start, floor, today.boundary.termOr<PrimaryBoundaryOptions>().sideOffsetRoundings, today.boundary.termOr<PrimaryBoundaryOptions>().minSideOffsetRoundings, d.mean, d.se(), sessions);
    // Converged: four times today's offsets move the estimate by under 0.1 % of the derivative
    // (1.7e-2), the difference's own noise allowed for. (The offsets of before moved it 0.7 %.)
    if (start == 4 * today.boundary.termOr<PrimaryBoundaryOptions>().sideOffsetRoundings) {
      EXPECT_LE(std::abs(d.mean), 1.7e-5 + kSigmas * d.se()) << "primary side offsets";
    }
  }
}

// The zoo knot (flat-shaded, 64 x 48, seen from the front) with a card and one point light.
std::string knotCardJson(const std::string& cardTransform, const std::string& lightPosition) {
  return R"({
  "materials": [{"name": "knot", "diffuse": {"albedo": {"constant": {"r": 0.75, "g": 0.35, "b": 0.2}}}},
                {"name": "white", "diffuse": {"albedo": {"constant": {"r": 0.8, "g": 0.8, "b": 0.8}}}}],
  "shapes": [
    {"name": "knot", "torus_knot": {}, "face_normals": true, "material": "knot",
     "transform": {"scale": {"x": 0.6, "y": 0.6, "z": 0.6}, "translate": {"y": 0.75}}},
    {"name": "card", "quad": {}, "material": "white", "transform": )" +
         cardTransform + R"(}],
  "lights": [{"name": "bulb", "point": {"position": )" +
         lightPosition + R"(, "intensity": {"r": 4.8, "g": 4.8, "b": 4.8}}}],
  "views": [{"eye": {"y": 1.2, "z": 3}, "target": {"y": 0.6}, "fov_y_degrees": 40}],
  "film": {"width": 64, "height": 48}})";
}

// The border term alone on a faceted, curved receiver: a card out of view near the knot's front
// fill casts its shadow on the still knot (its 0.5 px facets are the receivers, many of them seen
// or lit at a grazing angle), and moves in x and in y.
TEST(ShapeGradientDeep, CardShadowOnTheKnot) {
  ShapeCase c(knotCardJson(R"({"scale": {"x": 0.07, "y": 0.07, "z": 1}, "rotate_xyz_degrees": {"z": 20, "y": -45}, "translate": {"x": -1.2, "y": 0.95, "z": 1.2}})",
                           R"({"x": -1.5, "y": 1.0, "z": 1.5})"),
              "shapes/card/translation", {0.01f, 0.f, 0.f});
  GradientOptions o = shapeOptions(GradientMethod::Pt);
  o.boundary.samples = 16384;
  for (size_t k : {size_t(0), size_t(1)}) {
    const char* what = k == 0 ? "card x, its shadow on the knot" : "card y, its shadow on the knot";
    const MeanSE fd = validatedFd(c, k, 0.001f, what, 64);
    const Check r = runToPower(c, k, fd, o, what);
    expectMatches(r, what);
  }
}

// The knot moving through a still card's long shadow, lit from beside the camera (where its
// shadows on itself are thin): the border terms as the receiver moves, with the primary term. A
// diagnosis (prints): the border terms carry 1.6 % of this derivative.
TEST(ShapeGradientDeep, KnotThroughAStillShadow) {
  ShapeCase c(knotCardJson(R"({"scale": {"x": 0.035, "y": 0.3, "z": 1}, "rotate_xyz_degrees": {"z": 20}, "translate": {"x": 0.4, "y": 1.45, "z": 2.4}})",
                           R"({"x": 0.5, "y": 1.6, "z": 3.0})"),
              "shapes/knot/translation", {0.06f, -0.04f, 0.05f});
  const MeanSE fd = validatedFd(c, 0, 0.005f, "knot x through a still card's shadow", 64, false);
  GradientOptions o = shapeOptions(GradientMethod::Pt);
  o.boundary.samples = 16384;
  const int sessions = knotDiagnosisSessions();
  const Check r = run(c, 0, fd, o, sessions, "knot x through a still card's shadow");
  std::printf("  difference %+.2f %% (%.1f SE)\n", 100 * (r.est.mean - fd.mean) / fd.mean, (r.est.mean - fd.mean) / r.combined());
  GradientOptions noBorders = o;
  noBorders.boundary.secondary = false;
  run(c, 0, fd, noBorders, sessions, "  without the border terms");
}

// Vertex parameters (shapes/<s>/vertices): the derivative along a fixed pseudo-random direction of
// the whole vertex vector against finite differences along it.
std::vector<float> vertexDirection(size_t n, uint32_t seed, bool zOnly = false) {
  std::vector<float> d(n);
  uint32_t x = seed * 2654435761u + 12345u;
  for (size_t i = 0; i < n; ++i) {
    x = x * 1664525u + 1013904223u;
    d[i] = (zOnly && i % 3 != 2) ? 0.f : float(x >> 8) / float(1u << 24) * 2.f - 1.f;
  }
  return d;
}

// Every vertex of a mesh moved by one offset (where the rigid tests evaluate): n values.
std::vector<float> everyVertexMovedBy(size_t n, Vec3 d) {
  std::vector<float> o(n);
  for (size_t i = 0; i < n; ++i) o[i] = d[int(i % 3)];
  return o;
}

// The plane's four vertices lifted together (still a plane, so its diagonal has no jump and no
// boundary term applies), then bent along a direction that tilts each triangle its own way: the
// interior term through each hit triangle's position and normal is the whole derivative.
TEST(ShapeGradient, VertexInteriorTermAlone) {
  ShapeCase c(kPlaneScene, "shapes/plane/vertices", std::vector<float>(12, 0.f));
  ASSERT_EQ(c.theta.size(), 12u) << "a quad has four vertices";
  for (size_t i = 2; i < 12; i += 3) c.theta[i] += 0.1f;
  c.reg.write(c.theta, *c.scene);
  c.along = vertexDirection(12, 1, true);
  const MeanSE fd = validatedFd(c, 0, 0.004f, "plane vertices bent (interior only)");
  for (GradientMethod m : {GradientMethod::Pt, GradientMethod::Ris}) {
    const Check r = runToPower(c, 0, fd, shapeOptions(m), (std::string("plane vertices, ") + gradientMethodName(m)).c_str());
    expectMatches(r, "plane vertices");
    expectTermPower(r, "plane vertices");
  }
}

// The box of the crease scene (24 vertex copies at its face seams, 8 vertices as a parameter) bent
// out of shape: the crease in view moves and its faces turn, so the primary term at its edge points
// (each taken to the edge's two vertices) and the interior term both count. Dropping the primary
// term must fail. Copies move together, so the seams stay closed (an open seam would show).
TEST(ShapeGradient, VertexCreaseAndInterior) {
  std::vector<float> offset(24, 0.f);
  for (size_t i = 1; i < 24; i += 3) offset[i] = 0.05f;  // the box moved along y, as in CreaseTermAlone
  ShapeCase c(kCreaseScene, "shapes/box/vertices", offset);
  ASSERT_EQ(c.theta.size(), 24u) << "the box's copies at its seams are one vertex each";
  c.along = vertexDirection(24, 2);
  const MeanSE fd = validatedFd(c, 0, 0.004f, "box vertices, crease in view", 8);
  const Check r = runToPower(c, 0, fd, shapeOptions(GradientMethod::Pt), "box vertices, pt");
  expectMatches(r, "box vertices");
  GradientOptions noPrimary = shapeOptions(GradientMethod::Pt);
  noPrimary.boundary.primary = false;
  EXPECT_FALSE(run(c, 0, fd, noPrimary, 64, "box vertices, pt without the primary term").agrees());
}

// The card out of view bent under each kind of light: only its shadow is seen, so the shadow
// border (each edge point's derivative taken to its edge's two vertices) is the whole derivative.
TEST(ShapeGradient, VertexShadowBorderUnderAPointLight) {
  ShapeCase c(cardScene(false, false), "shapes/card/vertices", everyVertexMovedBy(12, Vec3(0.08f, -0.05f, 0.1f)));
  c.along = vertexDirection(12, 3);
  const MeanSE fd = validatedFd(c, 0, 0.004f, "card vertices out of view, point light", 16);
  const Check r = runToPower(c, 0, fd, shapeOptions(GradientMethod::Pt), "card vertices, point light, pt");
  expectMatches(r, "card vertices, point light");
  expectTermPower(r, "card vertices, point light");
}

// About 70 s: PT's plain light sampling needs up to 4096 sessions (2.3 ms each), and the reference
// 16 seeds: with 4, its standard error varied from 1.6e-6 to 1.0e-5 between equally valid random
// streams (the RIS renders' candidates drawn in another order), and only the smallest left room
// for PT's 6.2e-6 at 2048 sessions.
TEST(ShapeGradient, VertexShadowBorderUnderAnAreaLight) {
  ShapeCase c(cardScene(true, false), "shapes/card/vertices", everyVertexMovedBy(12, Vec3(0.08f, -0.05f, 0.1f)));
  c.along = vertexDirection(12, 4);
  const MeanSE fd = validatedFd(c, 0, 0.004f, "card vertices out of view, area light", 16);
  expectMatches(runToPower(c, 0, fd, shapeOptions(GradientMethod::Pt), "card vertices, area light, pt", {}, 1.0, 4096),
                "card vertices, area light, pt");
  expectMatches(runToPower(c, 0, fd, shapeOptions(GradientMethod::Restir), "card vertices, area light, restir"), "card vertices, area light");
}

void vertexShadowBorderUnderASky(int fdSeeds, int maxSessions, double claim) {
  ShapeCase c(skyScene(kCardLowBesideTheView), "shapes/card/vertices", everyVertexMovedBy(12, Vec3(0.25f, -0.04f, 0.05f)));
  c.along = vertexDirection(12, 5);
  const MeanSE fd = validatedFd(c, 0, 0.004f, "card vertices beside the view, constant sky", fdSeeds);
  GradientOptions o = shapeOptions(GradientMethod::Pt);
  o.boundary.samples = 8192;
  o.boundary.lightPoints = 64;
  expectMatches(runToPower(c, 0, fd, o, "card vertices, sky, pt", {}, 1.0, maxSessions, claim), "card vertices, sky", claim);
}

// The deep suite's (ShapeGradientDeep.VertexShadowBorderUnderASky): both sides are noisy here (a
// session's estimate spreads 0.9 times the derivative, a reference seed's 0.13), and 10 % takes
// 128 reference seeds, about four minutes. The default suite holds the environment's border term
// to 10 % in ShadowsUnderEnvironments and ShadowsUnderASunLobeSkyMap, and the vertices' share of a
// border in VertexShadowBorderUnderAPointLight and VertexShadowBorderUnderAnAreaLight.

// ReSTIR while the card deforms every step: the burn-in steps bend it towards the measured shape,
// so reused light samples and edge reservoirs were made in other geometries. The default tests
// their support against the vertices they were made with (kept per step with a BVH); the paper's
// shortcut tests it in the current geometry. Both are measured against FD.
// 60-100 s: the reference needs 16 seeds over two thirds of the film (the card in view and its
// shadow) for the h/2 check to reach 6 %; the sessions are a fifth of the time.
TEST(ShapeGradient, VertexRestirWhileTheMeshDeforms) {
  ShapeCase c(cardScene(true), "shapes/card/vertices", everyVertexMovedBy(12, Vec3(0.08f, -0.05f, 0.1f)));
  c.along = vertexDirection(12, 6);
  const MeanSE fd = validatedFd(c, 0, 0.004f, "card vertices in view, area light", 16);
  std::vector<float> approach = vertexDirection(12, 7);
  for (float& a : approach) a *= 0.02f;
  expectMatches(runToPower(c, 0, fd, shapeOptions(GradientMethod::Restir), "card vertices, restir after deformations", approach),
                "restir, support where made");
  GradientOptions shortcut = shapeOptions(GradientMethod::Restir);
  shortcut.boundary.multiViewShortcut = true;
  const Check r = run(c, 0, fd, shortcut, 16, "card vertices, restir shortcut after deformations", approach);
  std::printf("the shortcut: %s\n", r.agrees() ? "within 4 SE of FD here" : "differs from FD here");
}

TEST(ShapeGradient, VertexParametersRefuseWhatTheyCannotDo) {
  auto scene = test::sceneFromJson(cardScene(false).c_str());
  auto expectRefusal = [](auto&& call, const char* words) {
    try {
      call();
      ADD_FAILURE() << "accepted; expected an error with '" << words << "'";
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find(words), std::string::npos) << e.what();
    }
  };
  {
    ParameterRegistry reg;
    reg.add(*scene, "shapes/card/vertices");
    expectRefusal([&] { reg.add(*scene, "shapes/card/translation"); }, "has its vertices as a parameter");
    expectRefusal([&] { reg.add(*scene, "card.vertex_positions"); }, "listed twice");
    expectRefusal([&] { reg.add(*scene, "groups/props/rotation"); }, "has its vertices as a parameter");
  }
  {
    ParameterRegistry reg;
    reg.add(*scene, "shapes/box/rotation");
    expectRefusal([&] { reg.add(*scene, "shapes/box/vertices"); }, "already moves with a pose parameter");
    expectRefusal([&] { reg.add(*scene, "groups/props/vertices"); }, "not of a group");
  }
  {
    ParameterRegistry reg;
    EXPECT_EQ(reg.add(*scene, "box.positions").name, "box.positions");
    EXPECT_TRUE(reg.slots()[0].kind->isMesh());
    EXPECT_EQ(reg.slots()[0].size, 24u);
  }
}

// One component of a pose on its own (shapes/<s>/rotation/y): the same derivative, bit for bit,
// as that component of the whole rotation, from the same samples.
TEST(ShapeGradient, PoseComponentsAreParametersOnTheirOwn) {
  const std::string json = cardScene(false);
  auto whole = test::sceneFromJson(json.c_str()), one = test::sceneFromJson(json.c_str());
  ParameterRegistry all, y;
  all.add(*whole, "shapes/card/rotation");
  all.add(*whole, "groups/props/translation");
  y.add(*one, "shapes/card/rotation/y");
  y.add(*one, "groups/props/translation/z");
  ASSERT_EQ(y.size(), 2u);
  std::vector<float> a = all.read(*whole), b = y.read(*one);
  a[1] = b[0] = 4.f;
  a[5] = b[1] = 0.05f;
  all.write(a, *whole);
  y.write(b, *one);
  ASSERT_EQ(whole->meshes[1].positions, one->meshes[1].positions) << "the same pose";
  const Image target = renderView(*whole, 0, RenderOptions{}).image;
  GradientEngine ea(*whole, all, {target}, shapeOptions(GradientMethod::Pt)), eb(*one, y, {target}, shapeOptions(GradientMethod::Pt));
  EngineSession sa, sb;
  GradientRequest r;
  r.views = {0};
  r.seed = 3;
  const auto ga = ea.evaluate(r, sa).gradient, gb = eb.evaluate(r, sb).gradient;
  EXPECT_NE(ga[1], 0.0);
  EXPECT_EQ(ga[1], gb[0]);
  EXPECT_EQ(ga[5], gb[1]);
  ParameterRegistry bad;
  auto refused = [&](const char* name, const char* words) {
    try {
      bad.add(*one, name);
      ADD_FAILURE() << name << " was accepted";
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find(words), std::string::npos) << e.what();
    }
  };
  refused("shapes/card/scale/x", "one component: shapes/<name>/translation/x");
  refused("shapes/card/rotation/w", "one component");
  bad.add(*one, "shapes/card/translation/x");
  bad.add(*one, "shapes/card/translation/y");
  refused("shapes/card/translation", "listed twice");
  refused("shapes/card/translation/x", "listed twice");
}

TEST(ShapeGradient, UnsupportedJobsAreRefusedWithTheReason) {
  auto scene = test::sceneFromJson(cardScene(false).c_str());
  ParameterRegistry reg;
  reg.add(*scene, "shapes/card/translation");
  auto refusal = [&](GradientOptions o) {
    try {
      validateGradientJob(*scene, reg, o);
    } catch (const InputError& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  GradientOptions o = shapeOptions(GradientMethod::Pt);
  EXPECT_EQ(refusal(o), "");
  o.maxDepth = 2;
  EXPECT_NE(refusal(o).find("max_depth 1"), std::string::npos);
  EXPECT_EQ(refusal(shapeOptions(GradientMethod::Restir)), "");
  o = shapeOptions(GradientMethod::Pt);
  o.pixels.sampler = &pixelSampler("uniform");
  EXPECT_NE(refusal(o).find("pixel_sampler all"), std::string::npos);
  // Environments are accepted (their shadow borders have an estimator).
  auto sky = test::sceneFromJson(skyScene(kCardInView).c_str());
  ParameterRegistry skyReg;
  skyReg.add(*sky, "shapes/card/translation");
  EXPECT_NO_THROW(validateGradientJob(*sky, skyReg, shapeOptions(GradientMethod::Restir)));
  // A smooth-shaded moving mesh (the zoo sphere has vertex normals).
  auto smooth = test::sceneFromJson(R"({"materials": [{"name": "m", "diffuse": {}}],
    "shapes": [{"name": "ball", "sphere": {}, "material": "m"}],
    "lights": [{"name": "bulb", "point": {"position": {"z": 3}, "intensity": {"r": 1, "g": 1, "b": 1}}}],
    "views": [{"eye": {"z": 4}, "target": {}}], "film": {"width": 8, "height": 8}})");
  ParameterRegistry ballReg;
  ballReg.add(*smooth, "shapes/ball/translation");
  EXPECT_NO_THROW(validateGradientJob(*smooth, ballReg, shapeOptions(GradientMethod::Pt))) << "pose parameters move smooth meshes";
  ParameterRegistry ballVertices;
  ballVertices.add(*smooth, "shapes/ball/vertices");
  EXPECT_NO_THROW(validateGradientJob(*smooth, ballVertices, shapeOptions(GradientMethod::Pt))) << "vertex parameters move smooth meshes";
}

// A smooth-shaded sphere (interpolated normals) moving sideways over a floor under a point light.
// Before its material shaded by the geometric side, the shading normal's horizon inside the faces
// next to the silhouette was a moving jump no term sampled: here 1.2113e-2 against FD 1.2856e-2,
// 5.8 % low (10 SE), and the test fails so (checked). Now that curve carries no jump.
const char* kSmoothBallScene = R"({
  "materials": [{"name": "grey", "diffuse": {"albedo": {"constant": {"r": 0.6, "g": 0.5, "b": 0.4}}}},
                {"name": "white", "diffuse": {"albedo": {"constant": {"r": 0.8, "g": 0.8, "b": 0.8}}}}],
  "shapes": [
    {"name": "floor", "quad": {}, "material": "grey", "transform": {"scale": {"x": 4, "y": 4, "z": 1}}},
    {"name": "ball", "sphere": {"rings": 12}, "material": "white",
     "transform": {"scale": {"x": 0.5, "y": 0.5, "z": 0.5}, "rotate_xyz_degrees": {"z": 17}, "translate": {"x": 0.1, "y": 0.05, "z": 0.9}}}],
  "lights": [{"name": "bulb", "point": {"position": {"x": 1.5, "y": -0.8, "z": 4}, "intensity": {"r": 14, "g": 14, "b": 14}}}],
  "views": [{"eye": {"z": 4}, "target": {}, "up": {"y": 1}, "fov_y_degrees": 40}],
  "film": {"width": 40, "height": 40}})";

TEST(ShapeGradient, SmoothSphereMovingSideways) {
  ShapeCase c(kSmoothBallScene, "shapes/ball/translation", {0.08f, -0.05f, 0.f});
  ASSERT_FALSE(c.scene->meshes[1].normals.empty()) << "the sphere is smooth-shaded";
  const MeanSE fd = validatedFd(c, 0, 0.01f, "smooth sphere x, point light");
  // Claims 5 % (the 5.6 % error of old must not pass): sessions to 4 %.
  const Check r = runToPower(c, 0, fd, shapeOptions(GradientMethod::Pt), "smooth sphere x, pt", {}, 0.5);
  expectMatches(r, "smooth sphere x", 0.05);
}

// The smooth sphere under a point light 80 degrees from the view, seen close enough that its
// outline is off the film: the shadow terminator runs down the middle of the picture. There the
// renderer gives a face turned from the light no light (bsdfTowards) while its lit neighbour's
// interpolated normal still faces it, so the terminator's edges are radiance jumps that move with
// the sphere; the primary term samples them (PrimaryBoundary::terminatorJumpBound). Issue 59.
const char* kSideLitBallScene = R"({
  "materials": [{"name": "white", "diffuse": {"albedo": {"constant": {"r": 0.8, "g": 0.8, "b": 0.8}}}}],
  "shapes": [
    {"name": "ball", "sphere": {"rings": 12}, "material": "white",
     "transform": {"scale": {"x": 0.5, "y": 0.5, "z": 0.5}, "rotate_xyz_degrees": {"x": 23, "z": 17}, "translate": {"x": 0.1, "y": 0.05, "z": 0.9}}}],
  "lights": [{"name": "bulb", "point": {"position": {"x": 4.04, "y": 0.05, "z": 1.59}, "intensity": {"r": 30, "g": 30, "b": 30}}}],
  "views": [{"eye": {"x": 0.1, "y": 0.05, "z": 4}, "target": {"x": 0.1, "y": 0.05, "z": 0.9}, "up": {"y": 1}, "fov_y_degrees": 10}],
  "film": {"width": 40, "height": 40}})";

// The terminator's share of the derivative, measured by switching its candidates off; it must be
// large enough to matter and its absence must fail the comparison. Then every method, with the
// power to see a 10 % error in the term.
void expectTerminatorCarried(ShapeCase& c, const MeanSE& fd, const char* what) {
  GradientOptions without = shapeOptions(GradientMethod::Pt);
  without.boundary.term<PrimaryBoundaryOptions>().terminators = false;
  const Check w = run(c, 0, fd, without, 64, (std::string(what) + ", pt without the terminator").c_str());
  const double share = 1.0 - w.est.mean / fd.mean;
  std::printf("%s: the terminator carries %.1f %% of the derivative\n", what, 100 * share);
  EXPECT_GT(std::abs(share), 0.1) << what << ": the terminator should carry a good part of the derivative here";
  EXPECT_FALSE(w.agrees()) << what << ": without the terminator's edges the estimate must differ from FD";
  for (GradientMethod m : {GradientMethod::Pt, GradientMethod::Ris, GradientMethod::Restir}) {
    const std::string name = std::string(what) + ", " + gradientMethodName(m);
    const Check r = runToPower(c, 0, fd, shapeOptions(m), name.c_str(), {}, std::max(std::abs(share), 0.1));
    expectMatches(r, name.c_str());
    expectTermPower(r, (name + ", the terminator").c_str(), std::abs(share));
  }
}

TEST(ShapeGradient, SmoothSphereTerminatorUnderASideLight) {
  ShapeCase c(kSideLitBallScene, "shapes/ball/translation", {0.03f, -0.02f, 0.f});
  ASSERT_FALSE(c.scene->meshes[0].normals.empty()) << "the sphere is smooth-shaded";
  const MeanSE fd = validatedFd(c, 0, 0.004f, "side-lit smooth sphere x, point light");
  expectTerminatorCarried(c, fd, "side-lit smooth sphere x");
}

size_t parameterCount(const char* json, const char* name) {
  auto scene = test::sceneFromJson(json);
  ParameterRegistry reg;
  reg.add(*scene, name);
  return reg.size();
}

// The smooth sphere's vertices as a parameter: its normals are recomputed (welded, angle-weighted)
// after every update. All moved sideways together, the normals do not turn, and the derivative is
// the rigid one's, through the interior term's sliding hit and the silhouette.
TEST(ShapeGradient, SmoothSphereVerticesMovingSideways) {
  const size_t n = parameterCount(kSmoothBallScene, "shapes/ball/vertices");
  ShapeCase c(kSmoothBallScene, "shapes/ball/vertices", everyVertexMovedBy(n, Vec3(0.08f, -0.05f, 0.f)));
  ASSERT_FALSE(c.scene->meshes[1].normals.empty()) << "the sphere stays smooth-shaded";
  c.along = everyVertexMovedBy(n, Vec3(1.f, 0.f, 0.f));
  const MeanSE fd = validatedFd(c, 0, 0.01f, "smooth sphere vertices moved sideways, point light");
  // Claims 5 % (a 5 % error must not pass): sessions to 4 %.
  const Check r = runToPower(c, 0, fd, shapeOptions(GradientMethod::Pt), "smooth sphere vertices sideways, pt", {}, 0.5);
  expectMatches(r, "smooth sphere vertices sideways", 0.05);
}

// Sheared (z += x: towards the camera, so the outline barely moves), the recomputed normals turn
// as the sphere's sides tilt: the derivative through them (ParameterRegistry::foldNormalAdjoints)
// is a large share of the whole, measured by switching it off, and the test has the power to see a
// 10 % error in it. (Pseudo-random directions per vertex cancel out to a derivative too small to
// measure.) ReSTIR after deforming steps (pseudo-random ones) tests its reused samples against the
// normals of the geometry they were made in.
TEST(ShapeGradient, SmoothSphereVerticesSheared) {
  const size_t n = parameterCount(kSmoothBallScene, "shapes/ball/vertices");
  ShapeCase c(kSmoothBallScene, "shapes/ball/vertices", everyVertexMovedBy(n, Vec3(0.08f, -0.05f, 0.f)));
  double meanX = 0;
  for (size_t i = 0; i < n; i += 3) meanX += double(c.theta[i]) / double(n / 3);
  c.along.assign(n, 0.f);
  for (size_t i = 0; i < n; i += 3) c.along[i + 2] = float(double(c.theta[i]) - meanX) * 2.f;
  const MeanSE fd = validatedFd(c, 0, 0.004f, "smooth sphere vertices sheared, point light");
  GradientOptions without = shapeOptions(GradientMethod::Pt);
  without.vertexNormalTerm = false;
  const Check w = run(c, 0, fd, without, 32, "smooth sphere sheared, pt without the normals' term");
  const double share = 1.0 - w.est.mean / fd.mean;
  std::printf("smooth sphere sheared: the recomputed normals carry %.1f %% of the derivative\n", 100 * share);
  EXPECT_GT(share, 0.25) << "the normals' term should carry a good part of the derivative here";
  EXPECT_FALSE(w.agrees()) << "without the normals' term the estimate must differ from FD";
  const Check r = runToPower(c, 0, fd, shapeOptions(GradientMethod::Pt), "smooth sphere sheared, pt", {}, std::max(share, 0.1));
  expectMatches(r, "smooth sphere sheared");
  expectTermPower(r, "smooth sphere sheared, the normals' term", share);
  std::vector<float> approach = vertexDirection(n, 10);
  for (float& a : approach) a *= 0.01f;
  expectMatches(runToPower(c, 0, fd, shapeOptions(GradientMethod::Restir), "smooth sphere sheared, restir after deformations", approach),
                "smooth sphere sheared, restir");
}

// The side-lit sphere's vertices sheared across the film (x += 2 z about the mean depth: the side
// facing the camera slides sideways, the far side the other way): the faces tilt, their normals
// are recomputed, and the terminator moves across the picture.
TEST(ShapeGradient, SmoothSphereVerticesShearedTerminatorUnderASideLight) {
  const size_t n = parameterCount(kSideLitBallScene, "shapes/ball/vertices");
  ShapeCase c(kSideLitBallScene, "shapes/ball/vertices", everyVertexMovedBy(n, Vec3(0.03f, -0.02f, 0.f)));
  double meanZ = 0;
  for (size_t i = 0; i < n; i += 3) meanZ += double(c.theta[i + 2]) / double(n / 3);
  c.along.assign(n, 0.f);
  for (size_t i = 0; i < n; i += 3) c.along[i] = float(double(c.theta[i + 2]) - meanZ) * 2.f;
  const MeanSE fd = validatedFd(c, 0, 0.002f, "side-lit smooth sphere vertices sheared, point light", 8);
  expectTerminatorCarried(c, fd, "side-lit smooth sphere vertices sheared");
}

// A fine "scanned" mesh: a bumpy blob of 81920 flat-shaded triangles (an icosphere subdivided 6
// times, displaced), on a floor under a point light and a dim sky, one 64 x 64 view, so that a
// triangle covers about a third of a pixel. Issue 40's item 7: a pose job on such a mesh wandered
// off under Adam at 2.5 degrees and 0.025 per step. Here the pose gradient near the truth against
// FD, per component and method, separates gradient bias from the step size.
std::string fineBlobScene(int subdivisions = 6, int film = 64) {
  TriangleMesh m = makeIcosphere(subdivisions);
  for (Vec3& p : m.positions) {
    const float r = 1.f + 0.12f * std::sin(5.f * p.x + 1.f) * std::cos(4.f * p.y) + 0.08f * std::sin(9.f * p.z + 2.f * p.x) +
                    0.05f * std::cos(13.f * p.y + 7.f * p.z) + 0.3f * std::pow(std::max(0.f, p.z), 2.f);
    p = Vec3(p.x * r * 0.5f, p.y * r * 0.38f, p.z * r * 0.42f);
  }
  const std::filesystem::path path = std::filesystem::temp_directory_path() / ("invr_test_fine_blob" + std::to_string(subdivisions) + ".ply");
  writePly(path, m);
  return R"({"materials": [{"name": "m", "diffuse": {"albedo": {"constant": {"r": 0.7, "g": 0.65, "b": 0.6}}}}, {"name": "f", "diffuse": {}}],
  "shapes": [{"name": "floor", "quad": {}, "material": "f", "transform": {"scale": {"x": 4, "y": 4, "z": 1}}},
             {"name": "blob", "mesh": {"path": ")" + path.string() + R"("}, "material": "m", "transform": {"rotate_xyz_degrees": {"z": 20}, "translate": {"z": 0.55}}}],
  "lights": [{"name": "bulb", "point": {"position": {"x": 1, "y": -1, "z": 4}, "intensity": {"r": 14, "g": 14, "b": 14}}},
             {"name": "sky", "constant_environment": {"radiance": {"r": 0.3, "g": 0.3, "b": 0.3}}}],
  "views": [{"eye": {"x": 0.5, "y": -2.5, "z": 2.5}, "target": {"z": 0.4}, "up": {"z": 1}, "fov_y_degrees": 35}],
  "film": {"width": )" + std::to_string(film) + R"(, "height": )" + std::to_string(film) + R"(}})";
}

// The primary term traces an edge's two sides with the same random numbers (radianceJump): where
// they see nearly the same surface (creases between a fine mesh's facets) the light-sampling noise
// cancels. A 5120-triangle blob at 48 x 48: paired sessions with and without the primary term
// give the term's own spread. With a fork per side it was 96x the rest of the gradient's (sd 0.18
// against 0.0019 per session); now 8x (0.015), the silhouettes' share. The bound sits between.
TEST(ShapeGradient, PrimaryTermOfAFineMeshIsNotNoise) {
  ShapeCase c(fineBlobScene(4, 48), "shapes/blob/translation", {0.02f, -0.015f, 0.01f});
  GradientOptions with = shapeOptions(GradientMethod::Pt), without = with;
  without.boundary.primary = false;
  const MeanSE term = c.pairedDifference(0, with, without, 16, {});
  MeanSE rest;
  for (double g : c.perSession(0, without, 16, {})) rest.add(g);
  std::printf("fine blob x: the primary term %+.3e (sd %.2e per session), the rest %+.3e (sd %.2e)\n", term.mean, term.se() * 4, rest.mean, rest.se() * 4);
  EXPECT_LT(term.se(), 20 * rest.se());
}

TEST(ShapeGradientDeep, FineMeshPoseDiagnosis) {
  const std::string json = fineBlobScene();
  struct Component {
    const char* param;
    std::vector<float> offset;
    size_t k;
    float h;
    const char* what;
  };
  for (const Component& c : {Component{"shapes/blob/rotation", {2.f, -1.5f, 3.f}, 2, 0.5f, "fine blob, rotation z"},
                             Component{"shapes/blob/rotation", {2.f, -1.5f, 3.f}, 0, 0.5f, "fine blob, rotation x"},
                             Component{"shapes/blob/translation", {0.02f, -0.015f, 0.01f}, 0, 0.01f, "fine blob, translation x"}}) {
    ShapeCase sc(test::sceneFromJson(json.c_str()), c.param, c.offset, json, {1024, false});  // as documented
    const MeanSE fd = validatedFd(sc, c.k, c.h, c.what, 32);
    for (GradientMethod m : {GradientMethod::Pt, GradientMethod::Restir}) {
      const Check r = run(sc, c.k, fd, shapeOptions(m), 64, (std::string(c.what) + ", " + gradientMethodName(m)).c_str());
      std::printf("  ratio to fd %.3f\n", r.est.mean / fd.mean);
    }
    GradientOptions noPrimary = shapeOptions(GradientMethod::Pt), noSecondary = noPrimary;
    noPrimary.boundary.primary = false;
    noSecondary.boundary.secondary = false;
    run(sc, c.k, fd, noPrimary, 32, (std::string(c.what) + ", pt without the primary term").c_str());
    run(sc, c.k, fd, noSecondary, 32, (std::string(c.what) + ", pt without the shadow borders").c_str());
  }
}

TEST(ShapeGradient, DeterministicForAnyThreadCount) {
  for (const std::string& json : {cardScene(true), skyScene(kCardInView)}) {
    ShapeCase c(json, "shapes/card/translation", {0.08f, -0.05f, 0.1f});
    GradientOptions o = shapeOptions(GradientMethod::Ris);
    GradientEngine engine(*c.scene, c.reg, {c.target}, o);
    auto once = [&] {
      EngineSession session;
      GradientRequest r;
      r.views = {0};
      r.seed = 3;
      return engine.evaluate(r, session).gradient;
    };
    std::vector<double> one;
    tbb::task_arena(1).execute([&] { one = once(); });
    EXPECT_EQ(once(), one);
  }
}

// The default suite's cases that claim less than 10 % for time, at 10 %.
TEST(ShapeGradientDeep, RestirShadowsUnderAConstantSky) { cardBesideTheViewUnderASky(GradientMethod::Restir, 4096, 0.10); }
TEST(ShapeGradientDeep, VertexShadowBorderUnderASky) { vertexShadowBorderUnderASky(128, 8192, 0.10); }

}  // namespace
}  // namespace invr
