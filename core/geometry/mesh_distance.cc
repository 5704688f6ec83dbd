#include "core/geometry/mesh_distance.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "core/geometry/point_kd_tree.h"

namespace invr {

namespace {

Vec3 vertexOf(const TriangleMesh& m, size_t t, int k) { return m.positions[m.indices[3 * t + size_t(k)]]; }

// The closest point of triangle (a, b, c) to p (Ericson, Real-Time Collision Detection, 5.1.5).
Vec3 closestOnTriangle(Vec3 p, Vec3 a, Vec3 b, Vec3 c) {
  const Vec3 ab = b - a, ac = c - a, ap = p - a;
  const float d1 = dot(ab, ap), d2 = dot(ac, ap);
  if (d1 <= 0.f && d2 <= 0.f) return a;
  const Vec3 bp = p - b;
  const float d3 = dot(ab, bp), d4 = dot(ac, bp);
  if (d3 >= 0.f && d4 <= d3) return b;
  const float vc = d1 * d4 - d3 * d2;
  if (vc <= 0.f && d1 >= 0.f && d3 <= 0.f) return a + ab * (d1 / (d1 - d3));
  const Vec3 cp = p - c;
  const float d5 = dot(ab, cp), d6 = dot(ac, cp);
  if (d6 >= 0.f && d5 <= d6) return c;
  const float vb = d5 * d2 - d1 * d6;
  if (vb <= 0.f && d2 >= 0.f && d6 <= 0.f) return a + ac * (d2 / (d2 - d6));
  const float va = d3 * d6 - d5 * d4;
  if (va <= 0.f && (d4 - d3) >= 0.f && (d5 - d6) >= 0.f) return b + (c - b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6)));
  const float denom = 1.f / (va + vb + vc);
  return a + ab * (vb * denom) + ac * (vc * denom);
}

// Points spread over the surface by area: triangle i gets the samples whose stratified positions
// in [0, total area) fall into it, placed by a fixed low-discrepancy pair inside the triangle.
std::vector<Vec3> surfacePoints(const TriangleMesh& m, int n) {
  std::vector<double> cdf(m.triangleCount() + 1, 0.0);
  for (size_t t = 0; t < m.triangleCount(); ++t)
    cdf[t + 1] = cdf[t] + 0.5 * double(length(cross(vertexOf(m, t, 1) - vertexOf(m, t, 0), vertexOf(m, t, 2) - vertexOf(m, t, 0))));
  std::vector<Vec3> out;
  if (!(cdf.back() > 0.0) || n <= 0) return out;
  out.reserve(size_t(n));
  size_t t = 0;
  for (int i = 0; i < n; ++i) {
    const double x = (double(i) + 0.5) / double(n) * cdf.back();
    while (t + 1 < m.triangleCount() && cdf[t + 1] <= x) ++t;
    // The R2 sequence (plastic constant) inside the triangle, folded into it.
    double u = std::fmod(0.5 + 0.7548776662466927 * double(i), 1.0), v = std::fmod(0.5 + 0.5698402909980532 * double(i), 1.0);
    if (u + v > 1.0) { u = 1.0 - u; v = 1.0 - v; }
    const Vec3 a = vertexOf(m, t, 0), b = vertexOf(m, t, 1), c = vertexOf(m, t, 2);
    out.push_back(a + (b - a) * float(u) + (c - a) * float(v));
  }
  return out;
}

std::unique_ptr<PointKdIndex> centroidIndex(const TriangleMesh& m) {
  std::vector<float> xyz;
  xyz.reserve(3 * m.triangleCount());
  for (size_t t = 0; t < m.triangleCount(); ++t) {
    const Vec3 c = (vertexOf(m, t, 0) + vertexOf(m, t, 1) + vertexOf(m, t, 2)) / 3.f;
    xyz.insert(xyz.end(), {c.x, c.y, c.z});
  }
  return std::make_unique<PointKdIndex>(std::move(xyz), 16);
}

// Mean distance from the points to mesh m's surface, through the tree over m's centroids.
double meanDistanceTo(const std::vector<Vec3>& points, const TriangleMesh& m, const PointKdIndex& index) {
  if (points.empty() || m.triangleCount() == 0) return 0.0;
  constexpr size_t kCandidates = 16;
  const size_t k = std::min(kCandidates, m.triangleCount());
  double sum = 0;
  std::vector<uint32_t> ids(k);
  std::vector<float> d2(k);
  for (const Vec3& p : points) {
    const float q[3] = {p.x, p.y, p.z};
    const size_t found = index.tree.knnSearch(q, k, ids.data(), d2.data());
    float best = std::numeric_limits<float>::infinity();
    for (size_t j = 0; j < found; ++j) {
      const size_t t = ids[j];
      best = std::min(best, length(p - closestOnTriangle(p, vertexOf(m, t, 0), vertexOf(m, t, 1), vertexOf(m, t, 2))));
    }
    sum += double(best);
  }
  return sum / double(points.size());
}

}  // namespace

double symmetricChamferDistance(const TriangleMesh& a, const TriangleMesh& b, int samplesPerMesh) {
  return SurfaceDistance(a, samplesPerMesh).symmetricChamferTo(b);
}

struct SurfaceDistance::Index {
  std::unique_ptr<PointKdIndex> tree;
};

SurfaceDistance::SurfaceDistance(TriangleMesh mesh, int samples)
    : mesh_(std::move(mesh)), samples_(samples), points_(surfacePoints(mesh_, samples)), index_(std::make_unique<Index>()) {
  if (mesh_.triangleCount() > 0) index_->tree = centroidIndex(mesh_);
}

SurfaceDistance::~SurfaceDistance() = default;

double SurfaceDistance::symmetricChamferTo(const TriangleMesh& other) const {
  if (mesh_.triangleCount() == 0 || other.triangleCount() == 0) return 0.0;
  const auto otherTree = centroidIndex(other);
  return 0.5 * (meanDistanceTo(points_, other, *otherTree) + meanDistanceTo(surfacePoints(other, samples_), mesh_, *index_->tree));
}

double boundingBoxDiagonal(const TriangleMesh& mesh) {
  if (mesh.positions.empty()) return 0.0;
  Vec3 lo = mesh.positions[0], hi = lo;
  for (const Vec3& p : mesh.positions) {
    lo = vmin(lo, p);
    hi = vmax(hi, p);
  }
  return double(length(hi - lo));
}

}  // namespace invr
