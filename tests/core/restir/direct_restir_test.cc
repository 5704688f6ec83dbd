// ReSTIR at the estimator level: temporal reuse over a scripted parameter sequence stays unbiased
// with and without the M-cap; W = 0 whenever the target is 0; reservoirs follow moving surfaces.
#include "core/restir/direct_restir.h"

#include <gtest/gtest.h>

#include "test_util.h"

namespace invr {
namespace {

// Diffuse plane (albedo 0.6) under a 1x1 square area light (Le = 2) at height 1, plus a point
// light whose intensity changes every step.
constexpr const char* kToyScene = R"({
  "materials": [{"name": "plane", "diffuse": {"albedo": {"value": 0.6}}},
                {"name": "lamp", "diffuse": {"albedo": {"value": 0}}}],
  "shapes": [{"name": "plane", "material": "plane", "quad": {},
              "transform": {"scale": {"x": 10, "y": 10, "z": 1}, "rotate_xyz_degrees": {"x": -90}}},
             {"name": "lamp", "material": "lamp", "quad": {},
              "transform": {"scale": {"x": 0.5, "y": 0.5, "z": 1}, "rotate_xyz_degrees": {"x": 90}, "translate": {"y": 1}}}],
  "lights": [{"name": "lamp", "area": {"shape": "lamp", "radiance": {"r": 2, "g": 2, "b": 2}}},
             {"name": "bulb", "point": {"position": {"x": 1.0, "y": 1.2, "z": 0}, "intensity": {"r": 1, "g": 1, "b": 1}}}],
  "views": [{"eye": {"y": 5}, "target": {}, "up": {"z": -1}}]
})";

// A stored reservoir anchored at a surface hit, seen by view 0 (the camera above the plane).
StoredReservoir anchoredAt(const SurfaceHit& h) {
  StoredReservoir r;
  r.mesh = h.mesh;
  r.tri = h.tri;
  r.b1 = h.b1;
  r.b2 = h.b2;
  r.view = 0;
  return r;
}

double squareFormFactor(double half, double h) {  // point below the centre of a 2half x 2half square
  double X = half / h, sx = std::sqrt(1 + X * X);
  return 4 * (2 * X / sx * std::atan(X / sx)) / (2 * M_PI);
}

struct Toy {
  std::unique_ptr<Scene> scene = test::sceneFromJson(kToyScene);
  SurfaceHit hit;
  Bsdf bsdf;
  Toy() {
    EXPECT_TRUE(scene->intersect(Vec3(0, 0.5f, 0), Vec3(0, -1, 0), hit));
    bsdf = scene->materials[size_t(scene->meshMaterial[hit.mesh])].at(hit.uv);
  }
  ShadingPoint shading() const {
    ShadingPoint sp{&hit, &bsdf, Frame(hit.ns), Vec3(), Vec3(0, 1, 0)};
    sp.wo = sp.frame.toLocal(sp.woWorld);
    return sp;
  }
  double expected(float bulb) const {
    double r2 = 1.0 + 1.44;  // bulb at (1, 1.2, 0): clear of the lamp (which spans |x| <= 0.5)
    return 0.6 * 2.0 * squareFormFactor(0.5, 1.0) + 0.6 / M_PI * bulb * (1.2 / std::sqrt(r2)) / r2;
  }
};

void runChains(float mCap, const char* label) {
  Toy toy;
  RestirSettings s;
  s.candidates = 2;
  s.neighbours = 1;
  s.radius = 1.f;
  s.mCap = mCap;
  const int chains = 6000, steps = 6;
  std::vector<test::MeanSE> perStep(steps);
  double meanM = 0;
  for (int c = 0; c < chains; ++c) {
    ReservoirStore store;
    for (int t = 0; t < steps; ++t) {
      // Scripted theta: the bulb's intensity, which also changes the light-selection pmf.
      float bulb = 1.f + 0.8f * std::sin(float(t) * 1.3f);
      toy.scene->lights[1].intensity = Rgb(bulb);
      toy.scene->updateLightSelection();
      store.refresh(*toy.scene);
      Sampler sampler(RngKey{7, uint64_t(t), 0, uint64_t(c), 0});
      DirectPath p;
      Reservoir combined;
      ShadingPoint sp = toy.shading();
      double v = sampleDirectRestir(*toy.scene, sp, sampler, s, &store, nullptr, p, combined) ? p.contribution().x : 0.0;
      perStep[size_t(t)].add(v);
      StoredReservoir next = anchoredAt(toy.hit);
      next.r = StoredSample(combined);
      store.assign({next});
      if (t == steps - 1) meanM += combined.M / chains;
    }
  }
  for (int t = 0; t < steps; ++t) {
    float bulb = 1.f + 0.8f * std::sin(float(t) * 1.3f);
    EXPECT_NEAR(perStep[size_t(t)].mean * test::mutation(), toy.expected(bulb), test::kSigmas * perStep[size_t(t)].se())
        << label << " step " << t << " se " << perStep[size_t(t)].se();
    test::expectPower(std::string(label) + ", step " + std::to_string(t), perStep[size_t(t)].se(), toy.expected(bulb));
  }
  // Reuse really happened: confidence accumulated over the steps (up to the cap).
  EXPECT_GT(meanM, std::min(2.f * steps * 0.9f, mCap));
}

TEST(Restir, TemporalReuseUnbiasedWithoutCap) { runChains(1e9f, "no cap"); }
TEST(Restir, TemporalReuseUnbiasedWithCap) { runChains(4.f, "cap 4"); }

// Reuse while an occluder moves between steps (a shape job): a strip at height 0.5 hides a band
// of the lamp that slides every step. A reused sample's support must be tested in the geometry it
// was created in (§3.2): then every step's mean matches an independent reference (plain RIS, no
// reuse, at that step's geometry). The multi-view shortcut tests it in the current geometry: here
// a freshly uncovered part of the lamp counts the neighbour as able to produce it, and the
// estimate comes out low, which shows the test can tell the two apart.
TEST(Restir, ReuseWhileAnOccluderMovesTestsSupportWhereSamplesWereCreated) {
  // kToyScene with a strip appended to its shapes.
  const std::string strip = R"({"name": "strip", "material": "lamp", "quad": {},
      "transform": {"scale": {"x": 0.15, "y": 1, "z": 1}, "rotate_xyz_degrees": {"x": -90}, "translate": {"y": 0.5}}})";
  std::string json = kToyScene;
  const size_t end = json.find("],\n  \"lights\"");
  ASSERT_NE(end, std::string::npos);
  json.insert(end, ", " + strip);
  auto scene = test::sceneFromJson(json.c_str());
  const uint32_t stripMesh = uint32_t(scene->meshes.size() - 1);
  ASSERT_EQ(scene->meshNames[stripMesh], "strip");
  SurfaceHit hit;
  ASSERT_TRUE(scene->intersect(Vec3(0.02f, 0.3f, 0.01f), Vec3(0, -1, 0), hit));
  ASSERT_NE(hit.mesh, stripMesh);
  Bsdf bsdf = scene->materials[size_t(scene->meshMaterial[hit.mesh])].at(hit.uv);
  auto stripAt = [&](int t) {
    // The strip's shadow on the lamp spans x in 2c -+ 0.3 (from the shading point, at half height).
    scene->motion.mesh(stripMesh).translation.x = 0.3f * std::sin(1.9f * float(t));
    scene->applyShapeMotion({stripMesh});
  };
  auto estimate = [&](const RestirSettings& s, ReservoirStore* store, int t, uint64_t chain) {
    store->refresh(*scene);
    Sampler sampler(RngKey{13, uint64_t(t), 0, chain, 0});
    ShadingPoint sp{&hit, &bsdf, Frame(hit.ns), Vec3(), Vec3(0, 1, 0)};
    sp.wo = sp.frame.toLocal(sp.woWorld);
    DirectPath p;
    Reservoir combined;
    double v = sampleDirectRestir(*scene, sp, sampler, s, store, nullptr, p, combined) ? p.contribution().x : 0.0;
    StoredReservoir next = anchoredAt(hit);
    next.r = StoredSample(combined);
    next.pose = store->createdPose();
    store->assign({next});
    return v;
  };
  RestirSettings s;
  s.candidates = 2;
  s.neighbours = 1;
  s.radius = 1.f;
  s.mCap = 8.f;
  RestirSettings shortcut = s;
  shortcut.supportInCreatedGeometry = false;
  const int chains = 32000, steps = 5;
  std::vector<test::MeanSE> created(steps), current(steps), reference(steps);
  for (int c = 0; c < chains; ++c) {
    ReservoirStore a, b;
    for (int t = 0; t < steps; ++t) {
      stripAt(t);
      created[size_t(t)].add(estimate(s, &a, t, uint64_t(c)));
      current[size_t(t)].add(estimate(shortcut, &b, t, uint64_t(c)));
      ReservoirStore none;
      reference[size_t(t)].add(estimate(s, &none, t, uint64_t(c) + 1000000));
    }
    EXPECT_LE(a.poseCount(), 2u);  // the geometry of the stored reservoir, and the current one
  }
  bool shortcutBiased = false;
  for (int t = 0; t < steps; ++t) {
    const auto &e = created[size_t(t)], &r = reference[size_t(t)], &q = current[size_t(t)];
    const double se = std::sqrt(e.se() * e.se() + r.se() * r.se()), seq = std::sqrt(q.se() * q.se() + r.se() * r.se());
    std::printf("step %d: reference %.4f (se %.4f), created geometry %.4f, current geometry (shortcut) %.4f\n", t, r.mean, r.se(),
                e.mean, q.mean);
    EXPECT_NEAR(e.mean * test::mutation(), r.mean, test::kSigmas * se) << "step " << t;
    test::expectPower("step " + std::to_string(t) + ": created geometry against no reuse", se, r.mean);
    shortcutBiased = shortcutBiased || std::abs(q.mean - r.mean) > test::kSigmas * seq;
  }
  EXPECT_TRUE(shortcutBiased) << "the shortcut agreed at every step: this scene does not exercise the support test";
}

TEST(Restir, WeightIsZeroWhenTargetIsZero) {
  Toy toy;
  // Below the plane, looking up at its back: every light is on the other side.
  SurfaceHit below;
  ASSERT_TRUE(toy.scene->intersect(Vec3(0.1f, -1.f, 0.f), Vec3(0, 1, 0), below));
  ShadingPoint sp{&below, &toy.bsdf, Frame(below.ns), Vec3(), Vec3(0, -1, 0)};
  sp.wo = sp.frame.toLocal(sp.woWorld);
  // A neighbour with a perfectly good sample from above.
  ReservoirStore store;
  StoredReservoir good = anchoredAt(toy.hit);
  good.r.M = 10;
  good.r.W = 1.f;
  good.r.y.light = 1;
  store.assign({good});
  store.refresh(*toy.scene);
  RestirSettings s;
  s.normalDot = -1.f;  // accept it despite the flipped side
  s.radius = 5.f;
  for (int i = 0; i < 200; ++i) {
    Sampler sampler(RngKey{3, 0, 0, uint64_t(i)});
    DirectPath p;
    Reservoir r;
    EXPECT_FALSE(sampleDirectRestir(*toy.scene, sp, sampler, s, &store, nullptr, p, r));
    EXPECT_EQ(r.W, 0.f);
  }
  Reservoir empty;
  empty.wSum = 3.0;
  empty.targetY = 0.f;
  empty.finalize(4.f);
  EXPECT_EQ(empty.W, 0.f);
}

TEST(Restir, ReservoirsFollowTheSurfaceWhenTheMeshMoves) {
  Toy toy;
  ReservoirStore store;
  StoredReservoir r = anchoredAt(toy.hit);
  r.r.y.light = 0;
  r.r.y.tri = 1;
  r.r.y.b1 = 0.25f;
  r.r.y.b2 = 0.25f;
  store.assign({r});
  store.refresh(*toy.scene);
  Vec3 before = store.items()[0].p;
  LightSample lsBefore = evalLightSample(*toy.scene, r.r.y, before);

  // Lift the plane by 0.3 and move the lamp sideways by 0.2.
  auto plane = toy.scene->meshes[toy.hit.mesh].positions;
  for (auto& v : plane) v.y += 0.3f;
  toy.scene->updateMeshPositions(toy.hit.mesh, plane);
  uint32_t lamp = toy.scene->lights[0].mesh;
  auto lampPos = toy.scene->meshes[lamp].positions;
  for (auto& v : lampPos) v.x += 0.2f;
  toy.scene->updateMeshPositions(lamp, lampPos);
  store.refresh(*toy.scene);

  Vec3 after = store.items()[0].p;
  EXPECT_NEAR(after.y - before.y, 0.3f, 1e-5f);
  EXPECT_NEAR(after.x, before.x, 1e-5f);
  LightSample lsAfter = evalLightSample(*toy.scene, r.r.y, after);
  EXPECT_NEAR(lsAfter.lightPoint.x - lsBefore.lightPoint.x, 0.2f, 1e-5f);
  uint32_t found[4];
  EXPECT_EQ(store.neighbours(after, Vec3(0, 1, 0), 4, 0.01f, 0.9f, found), 1);
  EXPECT_EQ(store.neighbours(before, Vec3(0, 1, 0), 4, 0.01f, 0.9f, found), 0);
  // The surface moved, so a ray finds the plane at its new height.
  SurfaceHit h;
  ASSERT_TRUE(toy.scene->intersect(Vec3(0, 0.9f, 0), Vec3(0, -1, 0), h));
  EXPECT_NEAR(h.p.y, 0.3f, 1e-5f);
}


// Neighbour search: every result lies within the radius and passes the normal test, results are
// distinct, hints are taken first, and the pixel-window search equals a brute-force nearest search.
TEST(Restir, NeighbourSearchHonoursRadiusNormalsAndHints) {
  Toy toy;
  // A jittered 40 x 40 grid of shading points on the plane (spacing 0.01); every 7th one faces
  // the other way, so the normal test has something to reject.
  std::vector<StoredReservoir> items;
  Sampler jitter(RngKey{11, 0, 0, 0});
  for (int j = 0; j < 40; ++j)
    for (int i = 0; i < 40; ++i) {
      StoredReservoir r = anchoredAt(toy.hit);
      r.p = Vec3(0.01f * (float(i) + jitter.next1D()), 0.f, 0.01f * (float(j) + jitter.next1D()));
      r.setNormal((items.size() % 7 == 3) ? Vec3(0, -1, 0) : Vec3(0, 1, 0));
      items.push_back(r);
    }
  PixelSlots slots;
  slots.views = {2};
  slots.slotsPerView = items.size();
  for (size_t i = 0; i < items.size(); ++i) slots.item.push_back(uint32_t(i));
  ReservoirStore store;
  store.assignPlaced(items, toy.scene->geometryVersion(), slots);
  store.refresh(*toy.scene);
  ASSERT_NE(store.pixelSlots(2), nullptr);
  EXPECT_EQ(store.pixelSlots(2)[17], 17u);
  EXPECT_EQ(store.pixelSlots(0), nullptr);

  const Vec3 up(0, 1, 0);
  const float radius = 0.025f;
  uint32_t out[8];
  int withFour = 0;
  for (int q = 0; q < 400; ++q) {
    Vec3 p(0.05f + 0.3f * jitter.next1D(), 0.f, 0.05f + 0.3f * jitter.next1D());
    int n = store.neighbours(p, up, 4, radius, 0.9f, out);
    withFour += n == 4;
    for (int a = 0; a < n; ++a) {
      EXPECT_LE(length(items[out[a]].p - p), radius);
      EXPECT_GT(dot(items[out[a]].n(), up), 0.9f);
      for (int b = 0; b < a; ++b) EXPECT_NE(out[a], out[b]);
    }
  }
  EXPECT_GT(withFour, 390);  // about 15 acceptable points lie within the radius of each query

  // Hints come first even when another item is closer, and are not repeated.
  const Vec3 q(0.2f, 0.f, 0.2f);
  uint32_t pred = UINT32_MAX;
  float best = 0.f;
  for (uint32_t i = 0; i < items.size(); ++i) {
    float d = length(items[i].p - q);
    if (items[i].n().y > 0.f && d < radius && d > best) best = d, pred = i;  // the farthest acceptable one
  }
  ASSERT_NE(pred, UINT32_MAX);
  NeighbourHints hints;
  uint32_t tryFirst[2] = {pred, pred};
  hints.items = tryFirst;
  hints.count = 2;
  ASSERT_EQ(store.neighbours(q, up, 3, radius, 0.9f, out, &hints), 3);
  EXPECT_EQ(out[0], pred);
  EXPECT_NE(out[1], pred);
  EXPECT_NE(out[2], pred);
  // A hint outside the radius, or facing away, is not used.
  tryFirst[0] = 0;  // at the grid's corner, far from q
  hints.count = 1;
  ASSERT_EQ(store.neighbours(q, up, 1, radius, 0.9f, out, &hints), 1);
  EXPECT_NE(out[0], 0u);
  tryFirst[0] = 3;  // faces down
  ASSERT_EQ(store.neighbours(items[3].p, up, 1, radius, 0.9f, out, &hints), 1);
  EXPECT_NE(out[0], 3u);

  // The pixel-window search (one "pixel" per grid cell here) finds the nearest acceptable item,
  // the same as a brute-force search, and never builds the kd-tree.
  ASSERT_TRUE(store.slotsCover(2));
  EXPECT_FALSE(store.slotsCover(0));
  store.refresh(*toy.scene);
  NeighbourHints window;
  window.slots = store.pixelSlots(2);
  window.width = 40;
  window.height = 40;
  window.half = 4;  // radius 2.5 cells + one cell of jitter, rounded up
  for (int t = 0; t < 300; ++t) {
    window.x = 2 + int(jitter.next1D() * 36.f);
    window.y = 2 + int(jitter.next1D() * 36.f);
    Vec3 p(0.01f * (float(window.x) + jitter.next1D()), 0.f, 0.01f * (float(window.y) + jitter.next1D()));
    uint32_t nearest = UINT32_MAX;
    float nearestD = radius * radius;
    for (uint32_t i = 0; i < items.size(); ++i)
      if (items[i].n().y > 0.9f && lengthSquared(items[i].p - p) <= nearestD) nearestD = lengthSquared(items[i].p - p), nearest = i;
    ASSERT_EQ(store.neighbours(p, up, 1, radius, 0.9f, out, &window), 1);
    EXPECT_EQ(out[0], nearest);
  }
  EXPECT_FALSE(store.hasIndex());
  store.neighbours(q, up, 1, radius, 0.9f, out);  // no hints: the kd-tree, built on demand
  EXPECT_TRUE(store.hasIndex());
}

// The stored normal's 16-bit fixed point rounds to the nearest step, halves away from zero (as
// lround does), symmetrically for negative components, and clamps outside [-1, 1].
TEST(Restir, StoredNormalQuantisesToTheNearestStep) {
  StoredReservoir r;
  const float step = 1.f / 32767.f;
  r.setNormal(Vec3(1.f, -1.f, 0.f));
  EXPECT_EQ(r.nq[0], 32767);
  EXPECT_EQ(r.nq[1], -32767);
  EXPECT_EQ(r.nq[2], 0);
  r.setNormal(Vec3(1.5f, -2.f, 0.25f));  // 0.25 * 32767 = 8191.75
  EXPECT_EQ(r.nq[0], 32767);
  EXPECT_EQ(r.nq[1], -32767);
  EXPECT_EQ(r.nq[2], 8192);
  r.setNormal(Vec3(0.5f, -0.5f, -0.25f));  // 16383.5 exactly: a tie
  EXPECT_EQ(r.nq[0], 16384);
  EXPECT_EQ(r.nq[1], -16384);
  EXPECT_EQ(r.nq[2], -8192);
  Sampler rng(RngKey{5, 0, 0, 0, 0});
  for (int i = 0; i < 1000; ++i) {
    Vec3 n = normalize(Vec3(rng.next1D() - 0.5f, rng.next1D() - 0.5f, rng.next1D() - 0.5f));
    r.setNormal(n);
    for (int c = 0; c < 3; ++c) {
      EXPECT_NEAR(r.n()[c], n[c], 0.5f * step + 1e-7f);
      EXPECT_EQ(r.nq[c], int16_t(std::lround(n[c] * 32767.f)));
    }
  }
}

}  // namespace
}  // namespace invr
