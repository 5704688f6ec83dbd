#include "client/lab/embree_replay.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <atomic>
#include <stdexcept>

#include "core/stopwatch.h"

namespace invr::cli {

namespace {

RTCRay toRay(const LoggedRay& r) { return RTCRay{r.o.x, r.o.y, r.o.z, r.tnear, r.d.x, r.d.y, r.d.z, 0.f, r.tfar, 0xffffffffu, 0, 0}; }

double replaySingle(RTCScene handle, const std::vector<LoggedRay>& rays, bool allShadow, uint64_t& hits) {
  std::atomic<uint64_t> hitCount{0};
  Stopwatch clock;
  tbb::parallel_for(tbb::blocked_range<size_t>(0, rays.size(), 4096), [&](const tbb::blocked_range<size_t>& r) {
    uint64_t local = 0;
    RTCIntersectContext ctx;
    rtcInitIntersectContext(&ctx);
    for (size_t i = r.begin(); i < r.end(); ++i) {
      const LoggedRay& lr = rays[i];
      RTCScene scene = handle ? handle : lr.scene;
      if (allShadow || lr.shadow) {
        RTCRay ray = toRay(lr);
        rtcOccluded1(scene, &ctx, &ray);
        local += ray.tfar < 0.f;
      } else {
        RTCRayHit rh;
        rh.ray = toRay(lr);
        rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
        rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
        rtcIntersect1(scene, &ctx, &rh);
        local += rh.hit.geomID != RTC_INVALID_GEOMETRY_ID;
      }
    }
    hitCount += local;
  });
  const double s = clock.seconds();
  hits = hitCount;
  return s;
}

// Packets of N (RTCRayHitN / RTCRayN with rtcIntersectN / rtcOccludedN), in parallel chunks.
template <int N, typename HitN, typename RayN>
double replayPackets(const RayGroup& g, void (*intersect)(const int*, RTCScene, RTCIntersectContext*, HitN*),
                     void (*occluded)(const int*, RTCScene, RTCIntersectContext*, RayN*), uint64_t& hits) {
  std::atomic<uint64_t> hitCount{0};
  auto fill = [](RayN& r, const LoggedRay& lr, int k) {
    r.org_x[k] = lr.o.x; r.org_y[k] = lr.o.y; r.org_z[k] = lr.o.z; r.tnear[k] = lr.tnear;
    r.dir_x[k] = lr.d.x; r.dir_y[k] = lr.d.y; r.dir_z[k] = lr.d.z; r.time[k] = 0.f;
    r.tfar[k] = lr.tfar; r.mask[k] = 0xffffffffu; r.id[k] = 0; r.flags[k] = 0;
  };
  const std::vector<LoggedRay>& list = g.rays;
  Stopwatch clock;
  tbb::parallel_for(tbb::blocked_range<size_t>(0, (list.size() + N - 1) / N, 256), [&](const tbb::blocked_range<size_t>& r) {
    uint64_t local = 0;
    RTCIntersectContext ctx;
    rtcInitIntersectContext(&ctx);
    ctx.flags = RTC_INTERSECT_CONTEXT_FLAG_COHERENT;
    alignas(64) int valid[N];
    alignas(64) HitN rh{};
    alignas(64) RayN ray{};  // lanes past the end of the last packet are masked off by `valid`
    for (size_t p = r.begin(); p < r.end(); ++p) {
      const size_t first = p * N;
      for (int k = 0; k < N; ++k) {
        const size_t i = first + size_t(k);
        valid[k] = i < list.size() ? -1 : 0;
        if (i >= list.size()) continue;
        if (g.shadow) {
          fill(ray, list[i], k);
        } else {
          fill(rh.ray, list[i], k);
          rh.hit.geomID[k] = RTC_INVALID_GEOMETRY_ID;
          rh.hit.instID[0][k] = RTC_INVALID_GEOMETRY_ID;
        }
      }
      if (g.shadow) {
        occluded(valid, g.scene, &ctx, &ray);
        for (int k = 0; k < N; ++k) local += valid[k] && ray.tfar[k] < 0.f;
      } else {
        intersect(valid, g.scene, &ctx, &rh);
        for (int k = 0; k < N; ++k) local += valid[k] && rh.hit.geomID[k] != RTC_INVALID_GEOMETRY_ID;
      }
    }
    hitCount += local;
  });
  const double s = clock.seconds();
  hits = hitCount;
  return s;
}

// Streams: rtcIntersect1M / rtcOccluded1M over chunks of `chunk` rays, marked coherent.
double replayStreams(const RayGroup& g, size_t chunk, uint64_t& hits) {
  std::atomic<uint64_t> hitCount{0};
  const std::vector<LoggedRay>& list = g.rays;
  Stopwatch clock;
  tbb::parallel_for(tbb::blocked_range<size_t>(0, (list.size() + chunk - 1) / chunk, 1), [&](const tbb::blocked_range<size_t>& r) {
    uint64_t local = 0;
    RTCIntersectContext ctx;
    rtcInitIntersectContext(&ctx);
    ctx.flags = RTC_INTERSECT_CONTEXT_FLAG_COHERENT;
    std::vector<RTCRayHit> rh(chunk);
    std::vector<RTCRay> ray(chunk);
    for (size_t c = r.begin(); c < r.end(); ++c) {
      const size_t first = c * chunk, n = std::min(chunk, list.size() - first);
      for (size_t k = 0; k < n; ++k) {
        const RTCRay x = toRay(list[first + k]);
        if (g.shadow) {
          ray[k] = x;
        } else {
          rh[k].ray = x;
          rh[k].hit.geomID = RTC_INVALID_GEOMETRY_ID;
          rh[k].hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
        }
      }
      if (g.shadow) {
        rtcOccluded1M(g.scene, &ctx, ray.data(), unsigned(n), sizeof(RTCRay));
        for (size_t k = 0; k < n; ++k) local += ray[k].tfar < 0.f;
      } else {
        rtcIntersect1M(g.scene, &ctx, rh.data(), unsigned(n), sizeof(RTCRayHit));
        for (size_t k = 0; k < n; ++k) local += rh[k].hit.geomID != RTC_INVALID_GEOMETRY_ID;
      }
    }
    hitCount += local;
  });
  const double s = clock.seconds();
  hits = hitCount;
  return s;
}

double replayMode(const RayGroup& g, size_t mode, uint64_t& hits) {
  switch (mode) {
    case 0: return replaySingle(g.scene, g.rays, g.shadow, hits);
    case 1: return replayPackets<4, RTCRayHit4, RTCRay4>(g, rtcIntersect4, rtcOccluded4, hits);
    case 2: return replayPackets<8, RTCRayHit8, RTCRay8>(g, rtcIntersect8, rtcOccluded8, hits);
    case 3: return replayPackets<16, RTCRayHit16, RTCRay16>(g, rtcIntersect16, rtcOccluded16, hits);
    default: return replayStreams(g, 256, hits);
  }
}

}  // namespace

const std::vector<ReplayMode>& replayModes() {
  static const std::vector<ReplayMode> modes{{"single", "rtcIntersect1 / rtcOccluded1"},
                                             {"packet4", "rtcIntersect4 / rtcOccluded4, coherent"},
                                             {"packet8", "rtcIntersect8 / rtcOccluded8, coherent"},
                                             {"packet16", "rtcIntersect16 / rtcOccluded16, coherent"},
                                             {"stream", "rtcIntersect1M / rtcOccluded1M, 256-ray coherent streams"}};
  return modes;
}

size_t ReplayTimes::fastestMode(size_t group) const {
  const std::vector<double>& t = best.at(group);
  return size_t(std::min_element(t.begin(), t.end()) - t.begin());
}

double ReplayTimes::boundSeconds() const {
  double s = 0;
  for (size_t g = 0; g < best.size(); ++g) s += best[g][fastestMode(g)];
  return s;
}

double ReplayTimes::modeSeconds(size_t mode) const {
  double s = 0;
  for (const auto& t : best) s += t.at(mode);
  return s;
}

void replayOnce(const std::vector<RayGroup>& groups, ReplayTimes& times) {
  const size_t modes = replayModes().size();
  times.best.resize(groups.size(), std::vector<double>(modes, 1e30));
  for (size_t g = 0; g < groups.size(); ++g) {
    uint64_t singleHits = 0;
    for (size_t m = 0; m < modes; ++m) {
      uint64_t h = 0;
      times.best[g][m] = std::min(times.best[g][m], replayMode(groups[g], m, h));
      if (m == 0) {
        singleHits = h;
        const uint64_t logged = uint64_t(std::count_if(groups[g].rays.begin(), groups[g].rays.end(), [](const LoggedRay& r) { return r.hit; }));
        // The step traces some shadow rays as packets (EmbreeScene::occludedPacket), whose kernels
        // may round a ray grazing an edge differently from a single ray's: the same tolerance as
        // between replay modes. A geometry changed after the log differs by far more.
        if (double(std::max(h, logged) - std::min(h, logged)) > 1e-4 * double(groups[g].rays.size()) + 2.0)
          throw std::runtime_error("ray replay: single rays found " + std::to_string(h) + " hits among the " + groups[g].kind +
                                   " rays, the logged queries " + std::to_string(logged) + " (the geometry changed after the log)");
      } else if (double(std::max(h, singleHits) - std::min(h, singleHits)) > 1e-4 * double(groups[g].rays.size()) + 2.0)
        throw std::runtime_error(std::string("ray replay: ") + replayModes()[m].name + " found " + std::to_string(h) + " hits among the " +
                                 groups[g].kind + " rays, single rays " + std::to_string(singleHits));
    }
  }
}

std::vector<RayGroup> groupRays(const std::vector<LoggedRay>& rays, const std::vector<Vec3>& eyes) {
  static const char* const kKinds[] = {"camera", "bounce", "shadow", "boundary"};
  std::vector<RayGroup> groups;
  auto kindOf = [&](const LoggedRay& r) -> size_t {
    if (r.boundary) return 3;
    if (r.shadow) return 2;
    for (const Vec3& e : eyes)
      if (r.o.x == e.x && r.o.y == e.y && r.o.z == e.z) return 0;
    return 1;
  };
  for (const LoggedRay& r : rays) {
    const size_t k = kindOf(r);
    auto g = std::find_if(groups.begin(), groups.end(), [&](const RayGroup& x) { return x.kind == kKinds[k] && x.scene == r.scene && x.shadow == r.shadow; });
    if (g == groups.end()) {
      groups.push_back({kKinds[k], r.scene, r.shadow, {}});
      g = groups.end() - 1;
    }
    g->rays.push_back(r);
  }
  std::stable_sort(groups.begin(), groups.end(), [](const RayGroup& a, const RayGroup& b) {
    auto rank = [](const std::string& k) { return std::find(std::begin(kKinds), std::end(kKinds), k) - std::begin(kKinds); };
    return rank(a.kind) < rank(b.kind);
  });
  return groups;
}

double replayInOrder(const std::vector<LoggedRay>& rays, uint64_t& hits) { return replaySingle(nullptr, rays, false, hits); }

}  // namespace invr::cli
