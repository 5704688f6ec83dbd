#include "core/geometry/edge_topology.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <unordered_map>

namespace invr {

namespace {

struct CellHash {
  size_t operator()(const std::array<int64_t, 3>& c) const {
    uint64_t h = 1469598103934665603ull;
    for (int64_t v : c) h = (h ^ uint64_t(v)) * 1099511628211ull;
    return size_t(h);
  }
};

Vec3 faceNormalOf(const TriangleMesh& m, uint32_t f) {
  Vec3 a = m.positions[m.indices[3 * f]], b = m.positions[m.indices[3 * f + 1]], c = m.positions[m.indices[3 * f + 2]];
  Vec3 n = cross(b - a, c - a);
  float len = length(n);
  return len > 0.f ? n / len : Vec3(0.f);
}

// The shading normal face f uses at its corner that is mesh vertex v.
Vec3 cornerNormal(const TriangleMesh& m, uint32_t f, uint32_t weldedVertex, const std::vector<uint32_t>& weld) {
  for (int k = 0; k < 3; ++k) {
    uint32_t v = m.indices[3 * f + uint32_t(k)];
    if (weld[v] == weldedVertex) return m.normals.empty() ? faceNormalOf(m, f) : normalize(m.normals[v]);
  }
  return faceNormalOf(m, f);
}

}  // namespace

EdgeTopology EdgeTopology::build(const TriangleMesh& mesh, float weldTolerance) {
  EdgeTopology t;
  const size_t n = mesh.positions.size();
  Vec3 lo(std::numeric_limits<float>::infinity()), hi = -lo;
  for (const auto& p : mesh.positions) { lo = vmin(lo, p); hi = vmax(hi, p); }
  const float diag = n ? length(hi - lo) : 0.f;
  const float eps = std::max(weldTolerance * diag, std::numeric_limits<float>::min());
  // Weld: a hash grid with cells of size eps; a vertex joins the first welded vertex within eps in
  // its 27 neighbouring cells, so nearby copies straddling a cell border still weld.
  std::unordered_map<std::array<int64_t, 3>, std::vector<uint32_t>, CellHash> grid;
  t.weld_.assign(n, 0);
  std::vector<uint32_t> representative;  // welded id -> first mesh vertex
  for (uint32_t v = 0; v < n; ++v) {
    const Vec3 p = mesh.positions[v];
    std::array<int64_t, 3> cell{int64_t(std::floor((p.x - lo.x) / eps)), int64_t(std::floor((p.y - lo.y) / eps)),
                                int64_t(std::floor((p.z - lo.z) / eps))};
    uint32_t found = UINT32_MAX;
    for (int dx = -1; dx <= 1 && found == UINT32_MAX; ++dx)
      for (int dy = -1; dy <= 1 && found == UINT32_MAX; ++dy)
        for (int dz = -1; dz <= 1 && found == UINT32_MAX; ++dz) {
          auto it = grid.find({cell[0] + dx, cell[1] + dy, cell[2] + dz});
          if (it == grid.end()) continue;
          for (uint32_t w : it->second)
            if (length(mesh.positions[representative[w]] - p) <= eps) { found = w; break; }
        }
    if (found == UINT32_MAX) {
      found = uint32_t(representative.size());
      representative.push_back(v);
      grid[cell].push_back(found);
    }
    t.weld_[v] = found;
  }
  t.weldedCount_ = representative.size();

  // Edges by their welded end points; faces that welding collapsed (two corners on one vertex)
  // have no edges.
  struct Pending {
    uint32_t v0, v1, face0, face1 = MeshEdge::kNone, faces = 1;
    bool sameDirection = false;  // a second face runs along the edge as the first does (winding flips)
  };
  std::unordered_map<uint64_t, Pending> byKey;
  std::vector<uint64_t> order;  // first-seen order: deterministic edge indices
  const uint32_t faces = uint32_t(mesh.triangleCount());
  for (uint32_t f = 0; f < faces; ++f) {
    const uint32_t* idx = &mesh.indices[3 * f];
    if (t.weld_[idx[0]] == t.weld_[idx[1]] || t.weld_[idx[1]] == t.weld_[idx[2]] || t.weld_[idx[0]] == t.weld_[idx[2]]) continue;
    for (int k = 0; k < 3; ++k) {
      uint32_t a = idx[k], b = idx[(k + 1) % 3];
      uint32_t wa = t.weld_[a], wb = t.weld_[b];
      uint64_t key = (uint64_t(std::min(wa, wb)) << 32) | std::max(wa, wb);
      auto [it, fresh] = byKey.try_emplace(key, Pending{a, b, f});
      if (fresh) {
        order.push_back(key);
      } else {
        if (it->second.faces == 1) it->second.face1 = f;
        ++it->second.faces;
        if (t.weld_[it->second.v0] == wa) it->second.sameDirection = true;
      }
    }
  }
  t.edges_.reserve(order.size());
  for (uint64_t key : order) {
    const Pending& p = byKey[key];
    MeshEdge e;
    e.v0 = p.v0;
    e.v1 = p.v1;
    e.face0 = p.face0;
    e.face1 = p.face1;
    e.nonManifold = p.faces > 2;
    if (e.face1 != MeshEdge::kNone && !e.nonManifold) {
      // A crease where the shading normal the two faces use differs at either end point.
      for (uint32_t v : {p.v0, p.v1}) {
        Vec3 n0 = cornerNormal(mesh, e.face0, t.weld_[v], t.weld_), n1 = cornerNormal(mesh, e.face1, t.weld_[v], t.weld_);
        if (dot(n0, n1) < 1.f - 1e-5f) e.crease = true;
      }
    }
    t.boundary_ += e.boundary();
    t.creases_ += e.crease;
    t.nonManifold_ += e.nonManifold;
    t.closedOriented_ = t.closedOriented_ && !e.boundary() && !p.sameDirection;
    t.edges_.push_back(e);
  }
  t.closedOriented_ = t.closedOriented_ && !t.edges_.empty();
  return t;
}

void EdgeTopology::markEveryEdgeACrease() {
  creases_ = 0;
  for (MeshEdge& e : edges_) {
    if (!e.boundary()) e.crease = true;
    creases_ += e.crease;
  }
}

void EdgeTopology::markNoEdgeACrease() {
  creases_ = 0;
  for (MeshEdge& e : edges_) e.crease = false;
}

bool EdgeTopology::silhouetteFrom(const MeshEdge& e, const TriangleMesh& mesh, const std::vector<Vec3>& faceNormals, Vec3 o) {
  return silhouetteTowards(e, faceNormals, o - mesh.positions[e.v0]);
}

bool EdgeTopology::silhouetteTowards(const MeshEdge& e, const std::vector<Vec3>& faceNormals, Vec3 towards) {
  if (e.boundary()) return true;
  const float s0 = dot(faceNormals[e.face0], towards), s1 = dot(faceNormals[e.face1], towards);
  return (s0 > 0.f) != (s1 > 0.f);
}

}  // namespace invr
