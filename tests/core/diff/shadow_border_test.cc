// Where the shadow-border terms measure a border (shadow_border.h): at the border the renderer
// draws, whose shadow rays start an offset off the receiver, and between two points of the
// receiver's own plane. The case that tells them apart: a point light 4 degrees above a floor, so
// the drawn border lies 14 offsets (0.03 px) along the floor from the geometric one.
#include "core/diff/shadow_border.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

#include "test_util.h"

namespace invr {
namespace {

const char* kGrazingScene = R"({
  "materials": [{"name": "grey", "diffuse": {"albedo": {"constant": {"r": 0.6, "g": 0.5, "b": 0.4}}}}],
  "shapes": [
    {"name": "floor", "quad": {}, "material": "grey", "transform": {"scale": {"x": 8, "y": 8, "z": 1}}},
    {"name": "card", "quad": {}, "material": "grey",
     "transform": {"scale": {"x": 0.1, "y": 0.3, "z": 1}, "rotate_xyz_degrees": {"z": 3, "y": 90}, "translate": {"x": 3, "y": 0.05, "z": 0.12}}}],
  "lights": [{"name": "bulb", "point": {"position": {"x": 6, "y": 0.1, "z": 0.42}, "intensity": {"r": 400, "g": 400, "b": 400}}}],
  "views": [{"eye": {"z": 4}, "target": {}, "fov_y_degrees": 40}],
  "film": {"width": 40, "height": 40}})";

// What the light adds to the surface the camera sees through film point x (black for nothing).
Rgb throughTheFilm(const Scene& scene, Vec2 x, RayStats& rays) {
  const Camera& cam = scene.cameras[0];
  SurfaceHit hit;
  if (!scene.intersect(cam.eye, cam.direction(x.x, x.y, scene.width, scene.height), hit)) return Rgb(0.f);
  return deltaSourceRadiance(scene, hit, cam.eye, scene.lights[0], rays);
}

TEST(ShadowBorder, PointsAndSidesAreOnTheBorderTheRendererDraws) {
  std::unique_ptr<Scene> scene = test::sceneFromJson(kGrazingScene);
  ParameterRegistry reg;
  reg.add(*scene, "shapes/card/translation");
  std::vector<EdgeTopology> topology;
  for (const TriangleMesh& m : scene->meshes) topology.push_back(EdgeTopology::build(m));
  std::vector<ShadowEdge> edges;
  std::vector<float> weights;
  collectShadowEdges(*scene, reg, topology, ShadowSource::at(scene->lights[0].position), 0, edges, weights);
  ASSERT_FALSE(edges.empty());
  const Camera& cam = scene->cameras[0];
  RayStats rays;
  int points = 0, sidesStraddle = 0, filmStraddles = 0;
  for (const ShadowEdge& se : edges)
    for (int i = 0; i < 64; ++i) {
      ShadowBorderPoint bp;
      if (!shadowBorderPoint(*scene, reg, 0, ShadowSource::at(scene->lights[0].position), se, (float(i) + 0.5f) / 64.f, bp, rays)) continue;
      ++points;
      // Both sides lie on the receiver's triangle's plane, on that triangle's surface record.
      for (const SurfaceHit& side : bp.side) {
        EXPECT_EQ(side.mesh, bp.hit.mesh);
        EXPECT_EQ(side.tri, bp.hit.tri);
        EXPECT_NEAR(dot(bp.hit.ng, side.p - bp.hit.p), 0.f, 1e-5f);
      }
      // The renderer's own shading lights exactly one side: they straddle the drawn border.
      const bool lit0 = !isBlack(deltaSourceRadiance(*scene, bp.side[0], cam.eye, scene->lights[0], rays));
      const bool lit1 = !isBlack(deltaSourceRadiance(*scene, bp.side[1], cam.eye, scene->lights[0], rays));
      sidesStraddle += lit0 != lit1;
      // The film point is the drawn border's: camera rays 2e-3 px either side of it (the drawn
      // border is 0.03 px from the geometric one here) see one side lit and the other not.
      const float eps = 2e-3f;
      const bool filmLit0 = !isBlack(throughTheFilm(*scene, Vec2(bp.x.x - eps * bp.n.x, bp.x.y - eps * bp.n.y), rays));
      const bool filmLit1 = !isBlack(throughTheFilm(*scene, Vec2(bp.x.x + eps * bp.n.x, bp.x.y + eps * bp.n.y), rays));
      filmStraddles += filmLit0 != filmLit1 && filmLit0 == lit0;
    }
  std::printf("%d border points on the film: sides straddle the drawn border at %d, film points 2e-3 px off them at %d\n", points,
              sidesStraddle, filmStraddles);
  ASSERT_GT(points, 16);
  EXPECT_EQ(sidesStraddle, points);
  EXPECT_EQ(filmStraddles, points);
}

}  // namespace
}  // namespace invr
