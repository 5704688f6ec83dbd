#include "core/geometry/mesh.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <map>
#include <unordered_map>

#include "core/error.h"
#include "core/math/rng.h"

namespace invr {

float TriangleMesh::triangleArea(size_t tri) const {
  Vec3 a = positions[indices[3 * tri]], b = positions[indices[3 * tri + 1]], c = positions[indices[3 * tri + 2]];
  return 0.5f * length(cross(b - a, c - a));
}

void TriangleMesh::transform(const Affine& xf) {
  for (auto& p : positions) p = xf.point(p);
  if (!normals.empty()) {
    // Normals transform with the inverse transpose; the cofactor matrix is that up to a scale.
    auto col = [&](int j) { return Vec3(xf.m[0][j], xf.m[1][j], xf.m[2][j]); };
    Vec3 c0 = cross(col(1), col(2)), c1 = cross(col(2), col(0)), c2 = cross(col(0), col(1));
    for (auto& n : normals) n = normalize(c0 * n.x + c1 * n.y + c2 * n.z);
  }
}

namespace {

// The angle-weighted sum of each vertex's triangle normals, before normalisation (shared by
// computeSmoothNormals and its adjoint so that the two cannot drift apart).
std::vector<Vec3> angleWeightedNormalSums(const TriangleMesh& m) {
  std::vector<Vec3> n(m.positions.size(), Vec3(0.f));
  for (size_t t = 0; t < m.triangleCount(); ++t) {
    const uint32_t* i = &m.indices[3 * t];
    Vec3 p[3] = {m.positions[i[0]], m.positions[i[1]], m.positions[i[2]]};
    Vec3 fn = cross(p[1] - p[0], p[2] - p[0]);
    if (!(lengthSquared(fn) > 0.f)) continue;
    fn = normalize(fn);
    for (int k = 0; k < 3; ++k) {
      Vec3 a = p[(k + 1) % 3] - p[k], b = p[(k + 2) % 3] - p[k];
      float la = length(a), lb = length(b);
      if (!(la > 0.f && lb > 0.f)) continue;
      float angle = std::acos(std::clamp(dot(a, b) / (la * lb), -1.f, 1.f));
      n[i[k]] += fn * angle;
    }
  }
  return n;
}

}  // namespace

void computeSmoothNormals(TriangleMesh& m, const std::vector<uint32_t>* weld) {
  std::vector<Vec3> n = angleWeightedNormalSums(m);
  if (weld) {  // each welded vertex's copies share the sum over all their triangles
    std::vector<Vec3> welded(n.size(), Vec3(0.f));
    for (size_t v = 0; v < n.size(); ++v) welded[(*weld)[v]] += n[v];
    for (size_t v = 0; v < n.size(); ++v) n[v] = welded[(*weld)[v]];
  }
  for (size_t v = 0; v < n.size(); ++v) {
    // A vertex no triangle gives a direction (isolated or only degenerate) keeps +z: unused.
    n[v] = lengthSquared(n[v]) > 0.f ? normalize(n[v]) : Vec3(0, 0, 1);
  }
  m.normals = std::move(n);
}

void computeSmoothNormalsAdjoint(const TriangleMesh& m, const std::vector<Vec3>& dNormals, std::vector<Vec3>& dPositions,
                                 const std::vector<uint32_t>* weld) {
  std::vector<Vec3> sums = angleWeightedNormalSums(m), dN = dNormals;
  if (weld) {  // the copies' sum is one normal: its adjoint is the sum of theirs
    std::vector<Vec3> welded(sums.size(), Vec3(0.f)), weldedD(sums.size(), Vec3(0.f));
    for (size_t v = 0; v < sums.size(); ++v) {
      welded[(*weld)[v]] += sums[v];
      weldedD[(*weld)[v]] += dNormals[v];
    }
    for (size_t v = 0; v < sums.size(); ++v) {
      sums[v] = welded[(*weld)[v]];
      dN[v] = weldedD[(*weld)[v]];
    }
  }
  // n_v = A_v / |A_v|: dA_v = (I - n n^T) dn_v / |A_v| (the +z of an empty sum is constant). Welded,
  // each copy's own sum enters A_w once, so its adjoint is A_w's.
  std::vector<Vec3> dSums(sums.size(), Vec3(0.f));
  for (size_t v = 0; v < sums.size(); ++v) {
    if (!(lengthSquared(sums[v]) > 0.f)) continue;
    const float len = length(sums[v]);
    const Vec3 n = sums[v] / len;
    dSums[v] = (dN[v] - n * dot(n, dN[v])) / len;
  }
  dPositions.assign(m.positions.size(), Vec3(0.f));
  for (size_t t = 0; t < m.triangleCount(); ++t) {
    const uint32_t* i = &m.indices[3 * t];
    const Vec3 p[3] = {m.positions[i[0]], m.positions[i[1]], m.positions[i[2]]};
    const Vec3 e1 = p[1] - p[0], e2 = p[2] - p[0], F = cross(e1, e2);
    if (!(lengthSquared(F) > 0.f)) continue;
    const float lenF = length(F);
    const Vec3 fn = F / lenF;
    Vec3 dFn(0.f);
    for (int k = 0; k < 3; ++k) {
      const Vec3 a = p[(k + 1) % 3] - p[k], b = p[(k + 2) % 3] - p[k];
      const float la = length(a), lb = length(b);
      if (!(la > 0.f && lb > 0.f)) continue;
      const Vec3& dA = dSums[i[k]];
      const float angle = std::acos(std::clamp(dot(a, b) / (la * lb), -1.f, 1.f));
      dFn += dA * angle;
      // The corner's angle: d angle / da = -(unit part of b across a) / |a|, and the same for b.
      const float dAngle = dot(dA, fn);
      const Vec3 ah = a / la, bh = b / lb;
      const Vec3 acrossA = bh - ah * dot(ah, bh), acrossB = ah - bh * dot(ah, bh);
      const float sA = length(acrossA), sB = length(acrossB);
      if (!(sA > 0.f && sB > 0.f) || dAngle == 0.f) continue;  // a straight corner: the clamp holds the angle
      const Vec3 ga = acrossA * (-dAngle / (la * sA)), gb = acrossB * (-dAngle / (lb * sB));
      dPositions[i[(k + 1) % 3]] += ga;
      dPositions[i[(k + 2) % 3]] += gb;
      dPositions[i[k]] -= ga + gb;
    }
    // fn = F / |F| with F = e1 x e2: dF = (I - fn fn^T) dfn / |F|; F's adjoint to e1 is e2 x dF,
    // to e2 is dF x e1 (the scalar triple product turned).
    const Vec3 dF = (dFn - fn * dot(fn, dFn)) / lenF;
    const Vec3 de1 = cross(e2, dF), de2 = cross(dF, e1);
    dPositions[i[1]] += de1;
    dPositions[i[2]] += de2;
    dPositions[i[0]] -= de1 + de2;
  }
}

void TriangleMesh::flipWinding(bool flipNormals) {
  for (size_t t = 0; t + 2 < indices.size(); t += 3) std::swap(indices[t + 1], indices[t + 2]);
  if (flipNormals)
    for (auto& n : normals) n = -n;
}

TriangleMesh makeDisk(int segments) {
  TriangleMesh m;
  m.positions.push_back({0, 0, 0});
  m.uvs.push_back({0, 0});
  for (int j = 0; j < segments; ++j) {
    float phi = 2.f * kPi * float(j) / float(segments);
    m.positions.push_back({std::cos(phi), std::sin(phi), 0});
    m.uvs.push_back({1.f, float(j) / float(segments)});  // (radius, angle / 2 pi)
  }
  for (int j = 0; j < segments; ++j) m.indices.insert(m.indices.end(), {0u, uint32_t(1 + j), uint32_t(1 + (j + 1) % segments)});
  return m;
}

TriangleMesh makeIcosphere(int subdivisions) {
  TriangleMesh m;
  const float t = (1.f + std::sqrt(5.f)) / 2.f;
  m.positions = {{-1, t, 0}, {1, t, 0}, {-1, -t, 0}, {1, -t, 0}, {0, -1, t}, {0, 1, t}, {0, -1, -t}, {0, 1, -t},
                 {t, 0, -1}, {t, 0, 1}, {-t, 0, -1}, {-t, 0, 1}};
  for (Vec3& p : m.positions) p = normalize(p);
  m.indices = {0, 11, 5, 0, 5, 1, 0, 1, 7, 0, 7, 10, 0, 10, 11, 1, 5, 9, 5, 11, 4, 11, 10, 2, 10, 7, 6, 7, 1, 8,
               3, 9, 4, 3, 4, 2, 3, 2, 6, 3, 6, 8, 3, 8, 9, 4, 9, 5, 2, 4, 11, 6, 2, 10, 8, 6, 7, 9, 8, 1};
  for (int s = 0; s < subdivisions; ++s) {
    std::map<std::pair<uint32_t, uint32_t>, uint32_t> midpoint;
    auto mid = [&](uint32_t a, uint32_t b) {
      auto key = std::minmax(a, b);
      auto [it, fresh] = midpoint.try_emplace({key.first, key.second}, uint32_t(m.positions.size()));
      if (fresh) m.positions.push_back(normalize(m.positions[a] + m.positions[b]));
      return it->second;
    };
    std::vector<uint32_t> next;
    next.reserve(m.indices.size() * 4);
    for (size_t f = 0; f < m.indices.size(); f += 3) {
      const uint32_t a = m.indices[f], b = m.indices[f + 1], c = m.indices[f + 2];
      const uint32_t ab = mid(a, b), bc = mid(b, c), ca = mid(c, a);
      next.insert(next.end(), {a, ab, ca, b, bc, ab, c, ca, bc, ab, bc, ca});
    }
    m.indices = std::move(next);
  }
  return m;
}

TriangleMesh makeGrid(int cells) {
  TriangleMesh m;
  const uint32_t n = uint32_t(cells);
  for (uint32_t y = 0; y <= n; ++y)
    for (uint32_t x = 0; x <= n; ++x) m.positions.push_back({-1.f + 2.f * float(x) / float(n), -1.f + 2.f * float(y) / float(n), 0.f});
  for (uint32_t y = 0; y < n; ++y)
    for (uint32_t x = 0; x < n; ++x) {
      const uint32_t v = y * (n + 1) + x;
      m.indices.insert(m.indices.end(), {v, v + 1, v + n + 2, v, v + n + 2, v + n + 1});
    }
  return m;
}

TriangleMesh makeHeightfield(int cells, const std::function<float(float, float)>& height) {
  TriangleMesh m = makeGrid(cells);
  for (Vec3& p : m.positions) {
    const float u = 0.5f * (p.x + 1.f), v = 0.5f * (p.y + 1.f);
    m.uvs.push_back({u, v});
    p.z = height(u, v);
  }
  return m;
}

TriangleMesh makeQuad() {
  TriangleMesh m;
  m.positions = {{-1, -1, 0}, {1, -1, 0}, {1, 1, 0}, {-1, 1, 0}};
  m.uvs = {{0, 0}, {1, 0}, {1, 1}, {0, 1}};
  m.indices = {0, 1, 2, 0, 2, 3};
  return m;
}

TriangleMesh makeBox() {
  TriangleMesh m;
  // Each face: normal axis, then two tangent axes ordered so the winding faces outward.
  for (int axis = 0; axis < 3; ++axis)
    for (int sign = -1; sign <= 1; sign += 2) {
      Vec3 n(0.f), u(0.f), v(0.f);
      n[axis] = float(sign);
      u[(axis + 1) % 3] = 1.f;
      v[(axis + 2) % 3] = 1.f;
      if (sign < 0) std::swap(u, v);
      uint32_t base = uint32_t(m.positions.size());
      Vec2 uv[4] = {{0, 0}, {1, 0}, {1, 1}, {0, 1}};
      Vec3 corners[4] = {n - u - v, n + u - v, n + u + v, n - u + v};
      for (int k = 0; k < 4; ++k) { m.positions.push_back(corners[k]); m.uvs.push_back(uv[k]); }
      for (uint32_t k : {0u, 1u, 2u, 0u, 2u, 3u}) m.indices.push_back(base + k);
    }
  return m;
}

TriangleMesh makeSphere(int rings) {
  TriangleMesh m;
  int segs = 2 * rings;
  for (int i = 0; i <= rings; ++i) {
    float theta = kPi * float(i) / float(rings);
    for (int j = 0; j <= segs; ++j) {
      float phi = 2.f * kPi * float(j % segs) / float(segs);  // exact seam
      Vec3 p(std::sin(theta) * std::cos(phi), std::cos(theta), -std::sin(theta) * std::sin(phi));
      m.positions.push_back(p);
      m.normals.push_back(p);
      m.uvs.push_back({float(j) / float(segs), 1.f - float(i) / float(rings)});
    }
  }
  for (int i = 0; i < rings; ++i)
    for (int j = 0; j < segs; ++j) {
      uint32_t a = uint32_t(i * (segs + 1) + j), b = a + 1, c = a + uint32_t(segs + 1), d = c + 1;
      // Skip the zero-area triangles at the poles.
      if (i != 0) { m.indices.insert(m.indices.end(), {a, c, b}); }
      if (i != rings - 1) { m.indices.insert(m.indices.end(), {b, c, d}); }
    }
  return m;
}

TriangleMesh makeCylinder(int segments, bool capped) {
  TriangleMesh m;
  for (int j = 0; j <= segments; ++j) {
    float phi = 2.f * kPi * float(j % segments) / float(segments);  // exact seam
    Vec3 n(std::cos(phi), std::sin(phi), 0.f);
    for (float z : {-1.f, 1.f}) {
      m.positions.push_back({n.x, n.y, z});
      m.normals.push_back(n);
      m.uvs.push_back({float(j) / float(segments), 0.5f * (z + 1.f)});
    }
  }
  for (int j = 0; j < segments; ++j) {
    uint32_t a = uint32_t(2 * j), b = a + 1, c = a + 2, d = a + 3;
    m.indices.insert(m.indices.end(), {a, c, d, a, d, b});
  }
  if (capped) {
    for (float z : {-1.f, 1.f}) {
      uint32_t center = uint32_t(m.positions.size());
      Vec3 n(0, 0, z);
      m.positions.push_back({0, 0, z}); m.normals.push_back(n); m.uvs.push_back({0.5f, 0.5f});
      for (int j = 0; j < segments; ++j) {
        float phi = 2.f * kPi * float(j) / float(segments);
        m.positions.push_back({std::cos(phi), std::sin(phi), z});
        m.normals.push_back(n);
        m.uvs.push_back({0.5f + 0.5f * std::cos(phi), 0.5f + 0.5f * std::sin(phi)});
      }
      for (int j = 0; j < segments; ++j) {
        uint32_t a = center + 1 + uint32_t(j), b = center + 1 + uint32_t((j + 1) % segments);
        if (z > 0) m.indices.insert(m.indices.end(), {center, a, b});
        else m.indices.insert(m.indices.end(), {center, b, a});
      }
    }
  }
  return m;
}

namespace {

constexpr int kStemSections = 6, kStemSides = 4;
int leafletRings(int leafSegments) { return std::max(2, leafSegments / 3); }

}  // namespace

uint64_t plantVertexCount(int leaves, int leafSegments) {
  const uint64_t leaflet = 1 + uint64_t(leafletRings(leafSegments)) * uint64_t(leafSegments + 1);
  return uint64_t(leaves) * (3 * leaflet + uint64_t((kStemSections + 1) * kStemSides));
}

uint64_t plantTriangleCount(int leaves, int leafSegments) {
  const uint64_t leaflet = uint64_t(leafSegments) * uint64_t(2 * leafletRings(leafSegments) - 1);
  return uint64_t(leaves) * (3 * leaflet + uint64_t(2 * kStemSections * kStemSides));
}

TriangleMesh makePlant(int leaves, int leafSegments, uint64_t seed) {
  TriangleMesh m;
  const int rings = leafletRings(leafSegments);
  m.positions.reserve(plantVertexCount(leaves, leafSegments));
  m.indices.reserve(3 * plantTriangleCount(leaves, leafSegments));
  const Vec3 up(0, 1, 0);
  for (int l = 0; l < leaves; ++l) {
    int draw = 0;
    auto uniform = [&] {  // the leaf's own numbers, independent of how many leaves there are
      return float(mix64(mix64(seed ^ 0x6f78616c6973ull) + uint64_t(l) * 0x9e3779b97f4a7c15ull + uint64_t(draw++)) >> 40) * 0x1p-24f;
    };
    // The stem: a quadratic Bezier that rises from near the origin, then arches out to its top.
    const float phi = 2.f * kPi * uniform(), spread = 0.6f * std::sqrt(uniform()), height = 0.45f + 0.55f * uniform();
    // Drawn one statement at a time: the order of a call's arguments is unspecified, and the plant
    // must not depend on the compiler (z first: the order the committed figures were made with).
    const float baseZ = 0.04f * (uniform() - 0.5f), baseX = 0.04f * (uniform() - 0.5f);
    const Vec3 base(baseX, 0.f, baseZ);
    const Vec3 top(spread * std::cos(phi), height, spread * std::sin(phi)), ctrl(base.x, 0.9f * height, base.z);
    auto stemAt = [&](float t) { return base * ((1 - t) * (1 - t)) + ctrl * (2 * t * (1 - t)) + top * (t * t); };
    const uint32_t stem0 = uint32_t(m.positions.size());
    for (int i = 0; i <= kStemSections; ++i) {
      const float t = float(i) / float(kStemSections);
      const Vec3 c = stemAt(t), tangent = normalize((ctrl - base) * (2 * (1 - t)) + (top - ctrl) * (2 * t));
      const Vec3 side = normalize(cross(tangent, std::abs(tangent.x) < 0.9f ? Vec3(1, 0, 0) : Vec3(0, 0, 1)));
      const Vec3 other = cross(tangent, side);
      for (int j = 0; j < kStemSides; ++j) {
        const float a = 2.f * kPi * float(j) / float(kStemSides);
        m.positions.push_back(c + (side * std::cos(a) + other * std::sin(a)) * 0.006f);
      }
    }
    for (int i = 0; i < kStemSections; ++i)
      for (int j = 0; j < kStemSides; ++j) {
        const uint32_t a = stem0 + uint32_t(i * kStemSides + j), b = stem0 + uint32_t(i * kStemSides + (j + 1) % kStemSides);
        m.indices.insert(m.indices.end(), {a, b, b + kStemSides, a, b + kStemSides, a + kStemSides});
      }
    // Three heart-shaped leaflets at the top, each a fan around the stem's tip: polar outline
    // R(theta) with the notch at theta = 0, folded up along the midrib and drooping outwards.
    const float psi = 2.f * kPi * uniform(), droop = 0.1f + 0.5f * uniform(), size = 0.07f + 0.04f * uniform();
    for (int k = 0; k < 3; ++k) {
      const float az = psi + 2.f * kPi * float(k) / 3.f;
      const Vec3 horizontal(std::cos(az), 0.f, std::sin(az));
      const Vec3 axis = horizontal * std::cos(droop) - up * std::sin(droop), across = normalize(cross(up, horizontal));
      const Vec3 normal = cross(axis, across);
      const uint32_t centre = uint32_t(m.positions.size());
      m.positions.push_back(top);
      constexpr float kHalfAngle = 1.0f;
      for (int r = 1; r <= rings; ++r)
        for (int j = 0; j <= leafSegments; ++j) {
          const float theta = kHalfAngle * (2.f * float(j) / float(leafSegments) - 1.f);
          const float radius = float(r) / float(rings) * size * (1.f - 0.45f * std::exp(-(theta / 0.2f) * (theta / 0.2f)));
          const float along = radius * std::cos(theta), side = radius * std::sin(theta);
          m.positions.push_back(top + axis * along + across * side + normal * (0.4f * side * side / size) - up * (0.5f * along * along / size));
        }
      auto vertex = [&](int r, int j) { return centre + 1 + uint32_t((r - 1) * (leafSegments + 1) + j); };
      for (int j = 0; j < leafSegments; ++j) m.indices.insert(m.indices.end(), {centre, vertex(1, j), vertex(1, j + 1)});
      for (int r = 1; r < rings; ++r)
        for (int j = 0; j < leafSegments; ++j)
          m.indices.insert(m.indices.end(), {vertex(r, j), vertex(r + 1, j), vertex(r + 1, j + 1), vertex(r, j), vertex(r + 1, j + 1), vertex(r, j + 1)});
    }
  }
  return m;
}

TriangleMesh makeTorusKnot(int p, int q, float tubeRadius, int segments, int tubeSegments) {
  auto curve = [&](float t) {
    float r = 2.f + std::cos(float(q) * t);
    return Vec3(r * std::cos(float(p) * t), r * std::sin(float(p) * t), -std::sin(float(q) * t)) / 3.f;
  };
  auto tangentAt = [&](float t) { return normalize(curve(t + 1e-3f) - curve(t - 1e-3f)); };
  // Parallel-transport a normal along the closed curve; it comes back rotated by the holonomy
  // angle, which is spread evenly over the rings so the tube closes without a twist at the seam.
  std::vector<Vec3> normals(size_t(segments) + 1), tangents(size_t(segments) + 1);
  Vec3 n = normalize(cross(tangentAt(0.f), Vec3(0, 0, 1)));
  for (int i = 0; i <= segments; ++i) {
    Vec3 t = tangentAt(2.f * kPi * float(i) / float(segments));
    n = normalize(n - t * dot(n, t));
    normals[size_t(i)] = n;
    tangents[size_t(i)] = t;
  }
  Vec3 n0 = normals[0], t0 = tangents[0];
  float twist = std::atan2(dot(cross(n0, normals[size_t(segments)]), t0), dot(n0, normals[size_t(segments)]));
  TriangleMesh m;
  for (int i = 0; i <= segments; ++i) {
    if (i == segments) {  // the closing ring repeats ring 0 exactly (only its uvs differ)
      for (int j = 0; j <= tubeSegments; ++j) {
        m.positions.push_back(m.positions[size_t(j)]);
        m.normals.push_back(m.normals[size_t(j)]);
        m.uvs.push_back({1.f, float(j) / float(tubeSegments)});
      }
      break;
    }
    Vec3 c = curve(2.f * kPi * float(i) / float(segments));
    Vec3 t = tangents[size_t(i)];
    float undo = -twist * float(i) / float(segments);
    Vec3 b0 = cross(t, normals[size_t(i)]);
    Vec3 normal = normals[size_t(i)] * std::cos(undo) + b0 * std::sin(undo);
    Vec3 binormal = cross(t, normal);
    for (int j = 0; j <= tubeSegments; ++j) {
      float a = 2.f * kPi * float(j % tubeSegments) / float(tubeSegments);
      Vec3 dir = normal * std::cos(a) + binormal * std::sin(a);
      m.positions.push_back(j == tubeSegments ? m.positions[m.positions.size() - size_t(tubeSegments)] : c + dir * tubeRadius);
      m.normals.push_back(dir);
      m.uvs.push_back({float(i) / float(segments), float(j) / float(tubeSegments)});
    }
  }
  uint32_t row = uint32_t(tubeSegments + 1);
  for (int i = 0; i < segments; ++i)
    for (int j = 0; j < tubeSegments; ++j) {
      uint32_t a = uint32_t(i) * row + uint32_t(j), b = a + 1, c = a + row, d = c + 1;
      m.indices.insert(m.indices.end(), {a, d, c, a, b, d});  // outward winding
    }
  return m;
}

size_t validateMesh(TriangleMesh& mesh, const std::string& what) {
  if (mesh.positions.empty() || mesh.indices.empty()) throw InputError(what + ": mesh is empty (no triangles)");
  if (mesh.indices.size() % 3 != 0) throw InputError(what + ": index count is not a multiple of 3");
  for (size_t i = 0; i < mesh.positions.size(); ++i)
    if (!isFinite(mesh.positions[i])) throw InputError(what + ": vertex " + std::to_string(i) + " is not finite");
  if (!mesh.normals.empty() && mesh.normals.size() != mesh.positions.size())
    throw InputError(what + ": " + std::to_string(mesh.normals.size()) + " normals for " + std::to_string(mesh.positions.size()) + " vertices");
  if (!mesh.uvs.empty() && mesh.uvs.size() != mesh.positions.size())
    throw InputError(what + ": " + std::to_string(mesh.uvs.size()) + " uvs for " + std::to_string(mesh.positions.size()) + " vertices");
  for (size_t i = 0; i < mesh.normals.size(); ++i)
    if (!isFinite(mesh.normals[i])) throw InputError(what + ": normal " + std::to_string(i) + " is not finite");
  for (size_t i = 0; i < mesh.uvs.size(); ++i)
    if (!std::isfinite(mesh.uvs[i].x) || !std::isfinite(mesh.uvs[i].y)) throw InputError(what + ": uv " + std::to_string(i) + " is not finite");
  for (uint32_t idx : mesh.indices)
    if (idx >= mesh.positions.size()) throw InputError(what + ": triangle index " + std::to_string(idx) + " out of range");
  // Remove degenerate triangles first: they carry no area and would break the edge count.
  std::vector<uint32_t> kept;
  kept.reserve(mesh.indices.size());
  size_t removed = 0;
  for (size_t t = 0; t < mesh.triangleCount(); ++t) {
    uint32_t a = mesh.indices[3 * t], b = mesh.indices[3 * t + 1], c = mesh.indices[3 * t + 2];
    if (a == b || b == c || a == c || !(mesh.triangleArea(t) > 0.f)) { ++removed; continue; }
    kept.insert(kept.end(), {a, b, c});
  }
  if (kept.empty()) throw InputError(what + ": mesh has zero area (every triangle is degenerate)");
  mesh.indices = std::move(kept);
  // Non-manifold check on positions (not vertex ids: seams duplicate vertices for uvs/normals).
  std::map<std::array<uint32_t, 3>, uint32_t> posId;
  std::vector<uint32_t> canon(mesh.positions.size());
  for (size_t i = 0; i < mesh.positions.size(); ++i) {
    std::array<uint32_t, 3> bits;
    std::memcpy(bits.data(), &mesh.positions[i], sizeof bits);
    canon[i] = posId.try_emplace(bits, uint32_t(i)).first->second;
  }
  std::unordered_map<uint64_t, int> edgeCount;
  for (size_t t = 0; t < mesh.triangleCount(); ++t)
    for (int k = 0; k < 3; ++k) {
      uint32_t a = canon[mesh.indices[3 * t + k]], b = canon[mesh.indices[3 * t + (k + 1) % 3]];
      if (a > b) std::swap(a, b);
      if (++edgeCount[(uint64_t(a) << 32) | b] > 2)
        throw InputError(what + ": mesh is non-manifold (an edge is shared by more than two triangles, triangle " +
                         std::to_string(t) + ")");
    }
  return removed;
}

double meshWindingNumber(const TriangleMesh& mesh, Vec3 p) {
  // Van Oosterom and Strackee: the solid angle of triangle (a, b, c) seen from the origin is
  // 2 atan2(a . (b x c), |a||b||c| + (a . b)|c| + (a . c)|b| + (b . c)|a|).
  double sum = 0.0;
  for (size_t f = 0; f < mesh.triangleCount(); ++f) {
    double v[3][3];
    for (int k = 0; k < 3; ++k) {
      const Vec3 q = mesh.positions[mesh.indices[3 * f + size_t(k)]] - p;
      v[k][0] = q.x, v[k][1] = q.y, v[k][2] = q.z;
    }
    auto dotd = [](const double* x, const double* y) { return x[0] * y[0] + x[1] * y[1] + x[2] * y[2]; };
    const double* a = v[0];
    const double* b = v[1];
    const double* c = v[2];
    const double bc[3] = {b[1] * c[2] - b[2] * c[1], b[2] * c[0] - b[0] * c[2], b[0] * c[1] - b[1] * c[0]};
    const double la = std::sqrt(dotd(a, a)), lb = std::sqrt(dotd(b, b)), lc = std::sqrt(dotd(c, c));
    sum += 2.0 * std::atan2(dotd(a, bc), la * lb * lc + dotd(a, b) * lc + dotd(a, c) * lb + dotd(b, c) * la);
  }
  return sum / (4.0 * 3.14159265358979323846);
}

}  // namespace invr
