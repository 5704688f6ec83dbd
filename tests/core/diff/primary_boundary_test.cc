// The primary boundary term alone against an analytic case: a diffuse quad facing the camera under
// a constant environment, moving in depth. Its radiance albedo * Le does not depend on where it
// is (the interior derivative is zero), so the whole derivative of the image is the boundary's:
// with a unit adjoint, d/dz of sum_p I_p = d(area in pixels)/dz * (albedo - 1) * Le per channel.
#include "core/diff/primary_boundary.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

#include <tbb/task_arena.h>

#include "test_util.h"

namespace invr {
namespace {

using test::kSigmas;
using test::MeanSE;

const char* kQuadScene = R"({
  "materials": [{"name": "grey", "diffuse": {"albedo": {"constant": {"r": 0.5, "g": 0.5, "b": 0.5}}}}],
  "shapes": [{"name": "q", "quad": {}, "material": "grey"}],
  "lights": [{"name": "sky", "constant_environment": {"radiance": {"r": 1, "g": 1, "b": 1}}}],
  "views": [{"eye": {"z": 4}, "target": {}, "fov_y_degrees": 40}],
  "film": {"width": 64, "height": 64}})";

struct QuadCase {
  std::unique_ptr<Scene> scene = test::sceneFromJson(kQuadScene);
  ParameterRegistry reg;
  std::vector<EdgeTopology> topology;
  GradientOptions options;
  QuadCase(GradientMethod method) {
    reg.add(*scene, "shapes/q/translation");
    reg.write(reg.read(*scene), *scene);
    topology.resize(scene->meshes.size());
    topology[0] = EdgeTopology::build(scene->meshes[0]);
    options.method = method;
    options.maxDepth = 1;
  }
  // One estimate of d(sum over pixels and channels of I)/dtheta with `samples` edge samples.
  std::vector<double> estimate(int samples, uint64_t seed, BoundaryPassStats* stats = nullptr) {
    EstimatorSetup es{*scene, reg, options, 0, 1, nullptr};
    auto estimator = options.method == GradientMethod::Pt ? makePtEstimator(es) : makeRisEstimator(es);
    Image adjoint(scene->width, scene->height, 3);
    for (auto& v : adjoint.data()) v = 1.f;
    GradientScratchPool scratch(reg.size());
    std::vector<double> g(reg.size(), 0.0);
    PrimaryBoundary boundary(*scene, reg, topology);
    BoundaryPassStats st = boundary.run({0, adjoint, *estimator, samples, seed, 0, scratch, g});
    if (stats) *stats = st;
    return g;
  }
};

TEST(PrimaryBoundary, QuadMovingInDepthMatchesTheAnalyticAreaDerivative) {
  // Area of the quad on the film at distance d: (2 * (H/2) / (tan(fov/2) d))^2 pixels.
  const double H = 64, tanHalf = std::tan(20.0 * 3.14159265358979 / 180.0), d = 4.0;
  const double dAreaDz = 2.0 * H * H / (tanHalf * tanHalf * d * d * d);  // moving towards the eye
  const double expected = 3.0 * dAreaDz * (0.5 - 1.0);
  for (GradientMethod method : {GradientMethod::Pt, GradientMethod::Ris}) {
    QuadCase s(method);
    MeanSE z, x, y;
    BoundaryPassStats st;
    for (uint64_t seed = 0; seed < 16; ++seed) {
      auto g = s.estimate(4000, 1000 + seed, &st);
      x.add(g[0]);
      y.add(g[1]);
      z.add(g[2]);
    }
    // From the eye the quad's 4 rim edges are silhouettes (boundary edges); the diagonal is not.
    EXPECT_EQ(st.candidateEdges, 4u);
    EXPECT_NEAR(st.filmLength, 4 * 2 * H / (2 * tanHalf * d), 1e-2);
    SCOPED_TRACE(gradientMethodName(method));
    z.mean *= test::mutation();
    std::printf("%s: dI/dz %.3f +- %.3f (analytic %.3f); dI/dx %.3f +- %.3f\n", gradientMethodName(method), z.mean, z.se(), expected, x.mean,
                x.se());
    EXPECT_NEAR(z.mean, expected, kSigmas * z.se()) << "SE " << z.se();
    const std::string m = gradientMethodName(method);
    test::expectPower(m + ": dI/dz", z.se(), expected);
    // Sideways the pixel sum does not change while the quad stays on the film: zero, where a
    // sideways derivative a tenth the size of dI/dz would show.
    EXPECT_NEAR(x.mean, 0.0, kSigmas * x.se() + 1e-9);
    EXPECT_NEAR(y.mean, 0.0, kSigmas * y.se() + 1e-9);
    test::expectPower(m + ": dI/dx = 0, against the size of dI/dz", x.se(), expected);
    test::expectPower(m + ": dI/dy = 0, against the size of dI/dz", y.se(), expected);
  }
}

TEST(PrimaryBoundary, SameNumbersForAnyThreadCount) {
  QuadCase s(GradientMethod::Pt);
  auto a = s.estimate(3000, 7);
  std::vector<double> b;
  {
    tbb::task_arena one(1);
    one.execute([&] { b = s.estimate(3000, 7); });
  }
  EXPECT_EQ(a, b);
}

// A smooth sphere seen from the front under one light of each kind: its shadow terminator, the
// edges between a face the light reaches and one it cannot, must be among the candidates
// (Issue 59). The reference classifies every edge here from the definitions alone.
std::string smoothBallUnder(const std::string& light, const std::string& extraShape = "") {
  return R"({"materials": [{"name": "m", "diffuse": {}}],
    "shapes": [{"name": "ball", "sphere": {"rings": 12}, "material": "m",
                "transform": {"scale": {"x": 0.5, "y": 0.5, "z": 0.5}, "rotate_xyz_degrees": {"x": 23, "z": 17}}})" +
         extraShape + R"(],
    "lights": [)" + light + R"(],
    "views": [{"eye": {"z": 4}, "target": {}, "fov_y_degrees": 30}], "film": {"width": 32, "height": 32}})";
}

struct BallCandidates {
  std::unique_ptr<Scene> scene;
  ParameterRegistry reg;
  std::vector<EdgeTopology> topology;
  std::vector<PrimaryBoundary::Candidate> candidates;
  explicit BallCandidates(const std::string& json, bool terminators = true) : scene(test::sceneFromJson(json.c_str())) {
    reg.add(*scene, "shapes/ball/translation");
    for (const TriangleMesh& m : scene->meshes) topology.push_back(EdgeTopology::build(m));
    PrimaryBoundaryOptions options;
    options.terminators = terminators;
    candidates = PrimaryBoundary(*scene, reg, topology, options).candidates(0);
  }
  // Per edge of the ball: its kind among the candidates, or none.
  std::vector<int> kinds() const {
    std::vector<int> k(topology[0].edges().size(), -1);
    for (const auto& c : candidates)
      if (c.mesh == 0) k[c.edge] = int(c.kind);
    return k;
  }
  // Whether face f faces point q (its plane through edge e's first vertex).
  bool faces(const MeshEdge& e, uint32_t f, Vec3 q) const {
    return dot(scene->meshes[0].faceNormals[f], q - scene->meshes[0].positions[e.v0]) > 0.f;
  }
};

TEST(PrimaryBoundary, CandidatesHoldEveryFrontFacingEdgeOfAPointLightsTerminator) {
  const Vec3 light(3.9f, 0.2f, 0.7f);  // 80 degrees from the view
  BallCandidates b(smoothBallUnder(R"({"name": "bulb", "point": {"position": {"x": 3.9, "y": 0.2, "z": 0.7}, "intensity": {"r": 1, "g": 1, "b": 1}}})"));
  ASSERT_FALSE(b.scene->meshes[0].normals.empty());
  const std::vector<int> kinds = b.kinds();
  const Vec3 eye = b.scene->cameras[0].eye;
  int frontTerminators = 0, terminators = 0;
  for (size_t i = 0; i < kinds.size(); ++i) {
    const MeshEdge& e = b.topology[0].edges()[i];
    if (e.boundary()) continue;
    const bool front = b.faces(e, e.face0, eye) && b.faces(e, e.face1, eye);
    const bool split = b.faces(e, e.face0, light) != b.faces(e, e.face1, light);
    if (front && split) {
      ++frontTerminators;
      EXPECT_EQ(kinds[i], int(PrimaryBoundary::EdgeKind::Terminator)) << "edge " << i << " lies on the terminator, in view";
    }
    // Exact for point lights: nothing else is taken for a terminator.
    if (kinds[i] == int(PrimaryBoundary::EdgeKind::Terminator)) {
      ++terminators;
      EXPECT_TRUE(split) << "edge " << i << " has both faces on one side of the light";
    }
  }
  EXPECT_GE(frontTerminators, 6) << "the terminator crosses the visible side";
  // Switched off (as tests do to measure its share), the terminator's edges are not candidates.
  BallCandidates off(smoothBallUnder(R"({"name": "bulb", "point": {"position": {"x": 3.9, "y": 0.2, "z": 0.7}, "intensity": {"r": 1, "g": 1, "b": 1}}})"), false);
  for (const auto& c : off.candidates) EXPECT_NE(c.kind, PrimaryBoundary::EdgeKind::Terminator);
  std::printf("terminator edges: %d, %d of them with both faces towards the eye\n", terminators, frontTerminators);
}

TEST(PrimaryBoundary, CandidatesHoldTheTerminatorOfAnAreaLightAndEveryEdgeUnderASky) {
  // A 0.6-wide lamp at the side: an edge is a candidate if some point of the lamp lights one face
  // and not the other; the lamp's corners and centre are such points.
  const char* lampShape =
      R"(, {"name": "lamp", "quad": {}, "material": "m", "transform": {"scale": {"x": 0.3, "y": 0.3, "z": 1}, "rotate_xyz_degrees": {"y": -90}, "translate": {"x": 3}}})";
  BallCandidates area(smoothBallUnder(R"({"name": "lamp", "area": {"shape": "lamp", "radiance": {"r": 1, "g": 1, "b": 1}}})", lampShape));
  const std::vector<int> kinds = area.kinds();
  const Vec3 eye = area.scene->cameras[0].eye;
  int split = 0;
  for (size_t i = 0; i < kinds.size(); ++i) {
    const MeshEdge& e = area.topology[0].edges()[i];
    if (e.boundary() || !(area.faces(e, e.face0, eye) && area.faces(e, e.face1, eye))) continue;
    for (const Vec3& q : area.scene->meshes[1].positions)
      if (area.faces(e, e.face0, q) != area.faces(e, e.face1, q)) {
        ++split;
        EXPECT_EQ(kinds[i], int(PrimaryBoundary::EdgeKind::Terminator)) << "edge " << i << " is split by a corner of the lamp";
        break;
      }
  }
  EXPECT_GE(split, 6);
  // Under a sky every edge between two faces turned to the eye at an angle cuts it differently
  // (the diagonals inside the sphere's planar quads do not).
  BallCandidates sky(smoothBallUnder(R"({"name": "sky", "constant_environment": {"radiance": {"r": 1, "g": 1, "b": 1}}})"));
  const std::vector<int> skyKinds = sky.kinds();
  const std::vector<Vec3>& n = sky.scene->meshes[0].faceNormals;
  int angled = 0;
  for (size_t i = 0; i < skyKinds.size(); ++i) {
    const MeshEdge& e = sky.topology[0].edges()[i];
    if (e.boundary() || !(sky.faces(e, e.face0, eye) && sky.faces(e, e.face1, eye)) || !(length(n[e.face0] - n[e.face1]) > 1e-3f)) continue;
    ++angled;
    EXPECT_EQ(skyKinds[i], int(PrimaryBoundary::EdgeKind::Terminator)) << "edge " << i;
  }
  EXPECT_GE(angled, 100);
}

// A closed mesh seen from outside: creases between two faces turned away from the eye are never
// seen, and are left out (counted); seen from inside (a room), none is.
TEST(PrimaryBoundary, HiddenCreasesOfAClosedMeshSeenFromOutsideAreSkipped) {
  for (bool inside : {false, true}) {
    const std::string json = std::string(R"({"materials": [{"name": "m", "diffuse": {}}],
      "shapes": [{"name": "ball", "box": {}, "material": "m",
                  "transform": {"scale": {"x": )") + (inside ? "6" : "0.5") + R"(, "y": 0.7, "z": )" + (inside ? "6" : "0.5") +
                             R"(}, "rotate_xyz_degrees": {"x": 23, "y": 31, "z": 17}}}],
      "lights": [{"name": "bulb", "point": {"position": {"x": 0.3, "y": 0.2, "z": 0.4}, "intensity": {"r": 1, "g": 1, "b": 1}}}],
      "views": [{"eye": {"z": )" + (inside ? "0.2" : "4") + R"(}, "target": {}, "fov_y_degrees": 30}], "film": {"width": 32, "height": 32}})";
    auto scene = test::sceneFromJson(json.c_str());
    ParameterRegistry reg;
    reg.add(*scene, "shapes/ball/translation");
    std::vector<EdgeTopology> topology{EdgeTopology::build(scene->meshes[0])};
    ASSERT_TRUE(topology[0].closedOriented());
    size_t hidden = 0;
    const auto candidates = PrimaryBoundary(*scene, reg, topology).candidates(0, &hidden);
    const Vec3 eye = scene->cameras[0].eye;
    const TriangleMesh& mesh = scene->meshes[0];
    size_t away = 0, creases = 0;
    for (const MeshEdge& e : topology[0].edges()) {
      if (!e.crease || EdgeTopology::silhouetteFrom(e, mesh, mesh.faceNormals, eye)) continue;
      ++creases;
      away += dot(mesh.faceNormals[e.face0], eye - mesh.positions[e.v0]) < 0.f;
    }
    size_t creaseCandidates = 0;
    for (const auto& c : candidates) creaseCandidates += c.kind == PrimaryBoundary::EdgeKind::Crease;
    if (inside) {
      EXPECT_EQ(hidden, 0u) << "seen from inside, every face may be seen";
      EXPECT_EQ(creaseCandidates, creases);
    } else {
      EXPECT_GT(away, 0u);
      EXPECT_EQ(hidden, away) << "every crease turned away from the eye, and only those";
      EXPECT_EQ(creaseCandidates, creases - away);
    }
  }
}

}  // namespace
}  // namespace invr
