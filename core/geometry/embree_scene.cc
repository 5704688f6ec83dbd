#include "core/geometry/embree_scene.h"

#include <cstdlib>
#include <cstring>
#include <limits>
#include <stdexcept>
#include <string>

namespace invr {

EmbreeScene::EmbreeScene() {
  // INVR_EMBREE_CONFIG is passed to Embree as its device configuration, e.g. "isa=sse4.2" or
  // "isa=avx2": Embree picks its kernels by the CPU's instruction set, and their hits differ in
  // the last bits, so the suite is run with each forced to check that no verdict depends on the
  // machine (docs/testing.md).
  const char* config = std::getenv("INVR_EMBREE_CONFIG");
  device_ = rtcNewDevice(config && *config ? config : nullptr);
  if (!device_) throw std::runtime_error("Embree: cannot create device (error " + std::to_string(int(rtcGetDeviceError(nullptr))) + ")");
}

namespace {

// The lanes of an 8-wide packet from n <= 8 rays over [0, tmax[i]] (tmax null: infinite); the
// inactive lanes hold a copy of ray 0 (finite values) and are masked off in `valid`.
void fillPacket(int n, const Vec3* o, const Vec3* d, const float* tmax, RTCRay8& r, int* valid) {
  for (int i = 0; i < EmbreeScene::kPacket; ++i) {
    const int k = i < n ? i : 0;
    valid[i] = i < n ? -1 : 0;
    r.org_x[i] = o[k].x; r.org_y[i] = o[k].y; r.org_z[i] = o[k].z;
    r.dir_x[i] = d[k].x; r.dir_y[i] = d[k].y; r.dir_z[i] = d[k].z;
    r.tnear[i] = 0.f; r.tfar[i] = tmax ? tmax[k] : std::numeric_limits<float>::infinity();
    r.mask[i] = 0xffffffffu; r.flags[i] = 0; r.time[i] = 0.f; r.id[i] = unsigned(i);
  }
}

}  // namespace

void EmbreeScene::occludedPacket(int n, const Vec3* o, const Vec3* d, const float* tmax, bool* blocked) const {
  if (n <= 0) return;
  if (n == 1) {  // a packet of one costs more than a single ray
    blocked[0] = occluded(o[0], d[0], 0.f, tmax[0]);
    return;
  }
  if (n > kPacket) throw std::logic_error("EmbreeScene::occludedPacket: more than 8 rays");
  RTCIntersectContext ctx;
  rtcInitIntersectContext(&ctx);
  ctx.flags = RTC_INTERSECT_CONTEXT_FLAG_COHERENT;
  alignas(32) int valid[kPacket];
  alignas(32) RTCRay8 r;
  fillPacket(n, o, d, tmax, r, valid);
  rtcOccluded8(valid, scene_, &ctx, &r);
  for (int i = 0; i < n; ++i) {
    blocked[i] = r.tfar[i] < 0.f;  // Embree sets tfar = -inf on a hit
    if (observer_) observer_->record(scene_, o[i], d[i], 0.f, tmax[i], true, blocked[i]);
  }
}

void EmbreeScene::intersectPacket(int n, const Vec3* o, const Vec3* d, RayHit* hits, bool* found) const {
  if (n <= 0) return;
  if (n > kPacket) throw std::logic_error("EmbreeScene::intersectPacket: more than 8 rays");
  constexpr float inf = std::numeric_limits<float>::infinity();
  RTCIntersectContext ctx;
  rtcInitIntersectContext(&ctx);
  ctx.flags = RTC_INTERSECT_CONTEXT_FLAG_COHERENT;
  alignas(32) int valid[kPacket];
  alignas(32) RTCRayHit8 rh;
  fillPacket(n, o, d, nullptr, rh.ray, valid);
  for (int i = 0; i < kPacket; ++i) {
    rh.hit.geomID[i] = RTC_INVALID_GEOMETRY_ID;
    rh.hit.instID[0][i] = RTC_INVALID_GEOMETRY_ID;
  }
  rtcIntersect8(valid, scene_, &ctx, &rh);
  for (int i = 0; i < n; ++i) {
    found[i] = rh.hit.geomID[i] != RTC_INVALID_GEOMETRY_ID;
    if (found[i]) hits[i] = {rh.ray.tfar[i], rh.hit.geomID[i], rh.hit.primID[i], rh.hit.u[i], rh.hit.v[i]};
    if (observer_) observer_->record(scene_, o[i], d[i], 0.f, inf, false, found[i]);
  }
}

EmbreeScene::~EmbreeScene() {
  for (auto g : geoms_) rtcReleaseGeometry(g);
  if (scene_) rtcReleaseScene(scene_);
  if (device_) rtcReleaseDevice(device_);
}

void EmbreeScene::build(const std::vector<TriangleMesh>& meshes, const std::vector<bool>& dynamic) {
  for (auto g : geoms_) rtcReleaseGeometry(g);
  geoms_.clear();
  if (scene_) rtcReleaseScene(scene_);
  scene_ = rtcNewScene(device_);
  bool anyDynamic = false;
  size_t triangles = 0;
  for (const TriangleMesh& m : meshes) triangles += m.triangleCount();
  shadowPacketsPay_ = triangles <= kShadowPacketTriangles;
  for (size_t i = 0; i < meshes.size(); ++i) {
    const TriangleMesh& m = meshes[i];
    bool dyn = i < dynamic.size() && dynamic[i];
    anyDynamic |= dyn;
    RTCGeometry g = rtcNewGeometry(device_, RTC_GEOMETRY_TYPE_TRIANGLE);
    rtcSetGeometryBuildQuality(g, dyn ? RTC_BUILD_QUALITY_REFIT : RTC_BUILD_QUALITY_HIGH);
    // Embree reads vertex buffers with 16-byte loads: allocate one padding vertex.
    auto* v = static_cast<float*>(rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3,
                                                          sizeof(Vec3), m.positions.size() + 1));
    std::memcpy(v, m.positions.data(), m.positions.size() * sizeof(Vec3));
    auto* idx = static_cast<uint32_t*>(rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3,
                                                               3 * sizeof(uint32_t), m.triangleCount()));
    std::memcpy(idx, m.indices.data(), m.indices.size() * sizeof(uint32_t));
    rtcCommitGeometry(g);
    rtcAttachGeometryByID(scene_, g, unsigned(i));
    geoms_.push_back(g);
  }
  rtcSetSceneBuildQuality(scene_, anyDynamic ? RTC_BUILD_QUALITY_LOW : RTC_BUILD_QUALITY_HIGH);
  // Robust traversal for moving meshes: their edges are where boundary terms sample, and rays
  // grazing a refitted edge must not slip through it.
  if (anyDynamic) rtcSetSceneFlags(scene_, RTC_SCENE_FLAG_DYNAMIC | RTC_SCENE_FLAG_ROBUST);
  rtcCommitScene(scene_);
  if (rtcGetDeviceError(device_) != RTC_ERROR_NONE) throw std::runtime_error("Embree: scene build failed");
}

void EmbreeScene::updatePositions(uint32_t mesh, const std::vector<Vec3>& positions) {
  RTCGeometry g = geoms_.at(mesh);
  auto* v = static_cast<float*>(rtcGetGeometryBufferData(g, RTC_BUFFER_TYPE_VERTEX, 0));
  std::memcpy(v, positions.data(), positions.size() * sizeof(Vec3));
  rtcUpdateGeometryBuffer(g, RTC_BUFFER_TYPE_VERTEX, 0);
  rtcCommitGeometry(g);
  rtcCommitScene(scene_);
}

}  // namespace invr
