#include "core/geometry/ray_log.h"

#include <gtest/gtest.h>
#include <tbb/parallel_for.h>

#include <memory>
#include <stdexcept>

#include "core/geometry/embree_scene.h"
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

TEST(RayLog, RecordsEveryQueryAsTracedOnlyWhileAlive) {
  auto accel = quadAt(0);
  RayHit hit;
  EXPECT_TRUE(accel->intersect({0.2f, 0.3f, 5}, {0, 0, -1}, 0, 100, hit));  // before any log: not recorded
  std::vector<LoggedRay> rays;
  {
    RayLog log;
    EXPECT_EQ(RayLog::active(), &log);
    EXPECT_THROW(RayLog second, std::logic_error);
    EXPECT_TRUE(accel->intersect({0.2f, 0.3f, 5}, {0, 0, -1}, 0.5f, 100, hit));
    {
      const RayLog::BoundaryPhase boundary;
      EXPECT_FALSE(accel->occluded({0.2f, 0.3f, 5}, {0, 0, -1}, 0, 4.5f));
    }
    EXPECT_TRUE(accel->occluded({0.2f, 0.3f, 5}, {0, 0, -1}, 0, 5.5f));
    rays = log.take();
    EXPECT_TRUE(log.take().empty());  // take() empties the log
  }
  EXPECT_EQ(RayLog::active(), nullptr);
  EXPECT_FALSE(accel->occluded({0.2f, 0.3f, 5}, {0, 0, -1}, 0, 100) && RayLog::active());
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

TEST(RayLog, StopsRecordingButKeepsTheBvhsItSawAliveForTheReplay) {
  RayLog log;
  RTCScene handle;
  {
    auto accel = quadAt(-2);  // like a pose's BVH, gone before the replay
    handle = accel->handle();
    EXPECT_TRUE(accel->occluded({0.2f, 0.3f, 5}, {0, 0, -1}, 0, 100));
    log.stop();
    EXPECT_EQ(RayLog::active(), nullptr);
    EXPECT_TRUE(accel->occluded({0.2f, 0.3f, 5}, {0, 0, -1}, 0, 100));  // not recorded
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

TEST(RayLog, CollectsRaysFromEveryThread) {
  auto accel = quadAt(0);
  RayLog log;
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
  const RenderResult r = renderView(*scene, 0, opt);
  const std::vector<LoggedRay> rays = log.take();
  EXPECT_EQ(rays.size(), r.rays.total());
  size_t shadow = 0;
  for (const LoggedRay& x : rays) shadow += x.shadow;
  EXPECT_EQ(shadow, r.rays.shadow);
}

}  // namespace
}  // namespace invr
