#include "core/geometry/ray_log.h"

#include <gtest/gtest.h>
#include <tbb/parallel_for.h>

#include <memory>
#include <set>
#include <string>

#include "core/diff/gradient_engine.h"
#include "core/geometry/embree_scene.h"
#include "core/job/problem.h"
#include "core/job/zoo_jobs.h"
#include "core/render/renderer.h"
#include "core/scene/scene_builder.h"
#include "core/scene/zoo.h"

namespace invr {
namespace {

std::unique_ptr<EmbreeScene> quadAt(float z) {
  std::vector<TriangleMesh> meshes = {makeQuad()};
  meshes[0].transform(Affine::translate({0, 0, z}));
  auto accel = std::make_unique<EmbreeScene>();
  accel->build(meshes);
  return accel;
}

TEST(RayLog, RecordsEveryQueryOfTheScenesItObservesWhileAttached) {
  auto accel = quadAt(0), other = quadAt(1);
  RayHit hit;
  EXPECT_TRUE(accel->intersect({0.2f, 0.3f, 5}, {0, 0, -1}, 0, 100, hit));  // before any log: not recorded
  std::vector<LoggedRay> rays;
  RayLog log, second;
  accel->observe(&log);
  other->observe(&second);  // two logs at once, each of its own scene's rays
  EXPECT_EQ(accel->observer(), &log);
  EXPECT_TRUE(accel->intersect({0.2f, 0.3f, 5}, {0, 0, -1}, 0.5f, 100, hit));
  {
    const RayObserver::BoundaryPhase boundary(&log);
    EXPECT_FALSE(accel->occluded({0.2f, 0.3f, 5}, {0, 0, -1}, 0, 4.5f));
    EXPECT_TRUE(other->occluded({0.2f, 0.3f, 5}, {0, 0, -1}, 0, 100));  // another log's phase is its own
  }
  EXPECT_TRUE(accel->occluded({0.2f, 0.3f, 5}, {0, 0, -1}, 0, 5.5f));
  accel->observe(nullptr);
  EXPECT_TRUE(accel->occluded({0.2f, 0.3f, 5}, {0, 0, -1}, 0, 100));  // detached: not recorded
  rays = log.take();
  EXPECT_TRUE(log.take().empty());  // take() empties the log
  const std::vector<LoggedRay> others = second.take();
  ASSERT_EQ(others.size(), 1u);
  EXPECT_EQ(others[0].scene, other->handle());
  EXPECT_FALSE(others[0].boundary);
  ASSERT_EQ(rays.size(), 3u);
  EXPECT_EQ(rays[0].scene, accel->handle());
  EXPECT_FALSE(rays[0].shadow);
  EXPECT_TRUE(rays[0].hit);
  EXPECT_FALSE(rays[0].boundary);
  EXPECT_FLOAT_EQ(rays[0].tnear, 0.5f);
  EXPECT_FLOAT_EQ(rays[0].tfar, 100.f);
  EXPECT_FLOAT_EQ(rays[0].o.z, 5.f);
  EXPECT_FLOAT_EQ(rays[0].d.z, -1.f);
  EXPECT_TRUE(rays[1].shadow);
  EXPECT_FALSE(rays[1].hit);  // tfar 4.5 stops short of the quad
  EXPECT_TRUE(rays[1].boundary);
  EXPECT_FLOAT_EQ(rays[1].tfar, 4.5f);
  EXPECT_TRUE(rays[2].shadow);
  EXPECT_TRUE(rays[2].hit);
  EXPECT_FALSE(rays[2].boundary);
}

TEST(RayLog, KeepsTheBvhsItSawAliveForTheReplay) {
  RayLog log;
  RTCScene handle;
  {
    auto accel = quadAt(-2);  // like a pose's BVH, gone before the replay
    accel->observe(&log);
    handle = accel->handle();
    EXPECT_TRUE(accel->occluded({0.2f, 0.3f, 5}, {0, 0, -1}, 0, 100));
  }
  const std::vector<LoggedRay> rays = log.take();
  ASSERT_EQ(rays.size(), 1u);
  ASSERT_EQ(rays[0].scene, handle);
  RTCIntersectContext ctx;
  rtcInitIntersectContext(&ctx);
  RTCRay r{rays[0].o.x, rays[0].o.y, rays[0].o.z, rays[0].tnear, rays[0].d.x, rays[0].d.y, rays[0].d.z, 0.f, rays[0].tfar, 0xffffffffu, 0, 0};
  rtcOccluded1(rays[0].scene, &ctx, &r);
  EXPECT_LT(r.tfar, 0.f);  // still blocked by the quad at z = -2
}

// Scene::observeRays reaches every BVH a gradient step traces: the current one, a rigidly moving
// mesh's rest pose (support tests in an older pose) and the deformed poses of a vertex job, those
// built before the log was attached and those built after. Each step moves the parameters, so
// reused reservoirs come from older poses; every logged ray that is not the current BVH's went
// through one of those.
TEST(RayLog, SceneObserversSeeTheRaysOfEveryPoseBvh) {
  for (const char* job : {"pose", "octagon"}) {
    SCOPED_TRACE(job);
    Problem p = buildProblem(zooJob(job));
    GradientOptions o = p.gradient;
    o.method = GradientMethod::Restir;
    GradientEngine engine(*p.scene, p.params, std::vector<Image>(p.scene->cameras.size(), Image(p.scene->width, p.scene->height, 3)), o);
    EngineSession session;
    std::vector<float> theta = p.initial;
    auto step = [&](uint64_t k) {
      for (float& x : theta) x += 2e-3f;  // a small move of every parameter: a new pose each step
      p.params.write(theta, *p.scene);
      GradientRequest r;
      r.step = k;
      r.views = {0};
      engine.evaluate(r, session);
    };
    step(0);
    step(1);  // poses of earlier steps now exist
    RayLog log;
    p.scene->observeRays(&log);
    for (uint64_t k = 2; k < 5; ++k) step(k);
    p.scene->observeRays(nullptr);
    const std::vector<LoggedRay> rays = log.take();
    size_t elsewhere = 0;
    std::set<RTCScene> bvhs;
    for (const LoggedRay& x : rays) {
      elsewhere += x.scene != p.scene->accel.handle();
      bvhs.insert(x.scene);
    }
    EXPECT_GT(rays.size(), 10000u);
    EXPECT_GT(elsewhere, 0u) << "no ray logged through a pose's BVH";
    EXPECT_EQ(p.scene->rayObserver(), nullptr);
    // pose: its rest pose's BVH. octagon: a deformed pose per step; steps 2-4 reuse reservoirs of
    // poses 1 (built before the log was attached), 2 and 3 (built while it was).
    EXPECT_EQ(bvhs.size(), std::string(job) == "octagon" ? 4u : 2u) << elsewhere << " rays elsewhere";
  }
}

TEST(RayLog, CollectsRaysFromEveryThread) {
  auto accel = quadAt(0);
  RayLog log;
  accel->observe(&log);
  tbb::parallel_for(0, 20000, [&](int i) {
    const float x = float(i % 200) / 200.f - 0.5f;
    accel->occluded({x, 0.1f, 5}, {0, 0, -1}, 0, 100);
  });
  EXPECT_EQ(log.take().size(), 20000u);
}

// The renderer's ray statistics count exactly the Embree queries it makes, so a log taken around a
// render (bench rays, bench step) holds the rays those figures are about.
TEST(RayLog, HoldsExactlyTheRaysTheRendererCounts) {
  auto spec = zooScene("cornell");
  spec.mutable_film()->set_width(24);
  spec.mutable_film()->set_height(24);
  auto scene = buildScene(spec);
  RenderOptions opt;
  opt.spp = 2;
  opt.maxDepth = 3;
  RayLog log;
  scene->observeRays(&log);
  const RenderResult r = renderView(*scene, 0, opt);
  const std::vector<LoggedRay> rays = log.take();
  EXPECT_EQ(rays.size(), r.rays.total());
  size_t shadow = 0;
  for (const LoggedRay& x : rays) shadow += x.shadow;
  EXPECT_EQ(shadow, r.rays.shadow);
}

}  // namespace
}  // namespace invr
