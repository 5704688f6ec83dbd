// Welded edge topology: closed primitives have no boundary edges whatever their per-face vertex
// copies and seams; open ones have exactly their rims; creases where shading jumps; silhouettes
// from a viewpoint.
#include "core/geometry/edge_topology.h"

#include <gtest/gtest.h>

namespace invr {
namespace {

std::vector<Vec3> faceNormals(const TriangleMesh& m) {
  std::vector<Vec3> n(m.triangleCount());
  for (size_t f = 0; f < n.size(); ++f) {
    Vec3 a = m.positions[m.indices[3 * f]], b = m.positions[m.indices[3 * f + 1]], c = m.positions[m.indices[3 * f + 2]];
    n[f] = normalize(cross(b - a, c - a));
  }
  return n;
}

TEST(EdgeTopology, ClosedPrimitivesHaveNoBoundaryEdges) {
  struct Case {
    const char* name;
    TriangleMesh mesh;
  };
  Case cases[] = {{"box", makeBox()},
                  {"sphere 8", makeSphere(8)},
                  {"sphere 32", makeSphere(32)},
                  {"capped cylinder", makeCylinder(24, true)},
                  {"torus knot", makeTorusKnot(2, 3, 0.15f, 64, 8)}};
  for (auto& c : cases) {
    // The meshes really do carry copies: welding must be what closes them.
    EdgeTopology t = EdgeTopology::build(c.mesh);
    EXPECT_LT(t.weldedVertices(), c.mesh.positions.size()) << c.name;
    EXPECT_EQ(t.boundaryEdges(), 0u) << c.name;
    EXPECT_EQ(t.nonManifoldEdges(), 0u) << c.name;
    // A closed triangle mesh: every edge has two faces, so E = 3F/2 (over faces welding kept).
    EXPECT_EQ(2 * t.edges().size(), 3 * c.mesh.triangleCount()) << c.name;
  }
}

// Closed and consistently wound: the closed primitives, flipped or not; not an open one, nor a
// closed one with one face turned against its neighbours. The winding number about a point tells
// inside (+1 with outward normals, -1 flipped) from outside (0).
TEST(EdgeTopology, ClosedOrientedMeshesAndTheirWindingNumber) {
  for (TriangleMesh m : {makeBox(), makeSphere(8), makeCylinder(24, true), makeTorusKnot(2, 3, 0.15f, 64, 8)}) {
    EXPECT_TRUE(EdgeTopology::build(m).closedOriented());
    TriangleMesh flipped = m;
    flipped.flipWinding(false);
    EXPECT_TRUE(EdgeTopology::build(flipped).closedOriented());
  }
  EXPECT_FALSE(EdgeTopology::build(makeQuad()).closedOriented());
  EXPECT_FALSE(EdgeTopology::build(makeCylinder(16, false)).closedOriented());
  TriangleMesh box = makeBox();
  std::swap(box.indices[1], box.indices[2]);  // one face wound against its neighbours
  EXPECT_FALSE(EdgeTopology::build(box).closedOriented());

  TriangleMesh sphere = makeSphere(16);
  EXPECT_NEAR(meshWindingNumber(sphere, Vec3(0.1f, 0.2f, -0.3f)), 1.0, 1e-6) << "inside, outward normals";
  EXPECT_NEAR(meshWindingNumber(sphere, Vec3(0.f, 0.f, 4.f)), 0.0, 1e-6) << "outside";
  EXPECT_NEAR(meshWindingNumber(sphere, Vec3(1.5f, -0.2f, 0.3f)), 0.0, 1e-6) << "outside, close";
  sphere.flipWinding(true);
  EXPECT_NEAR(meshWindingNumber(sphere, Vec3(0.1f, 0.2f, -0.3f)), -1.0, 1e-6) << "inside, inward normals";
  const TriangleMesh knot = makeTorusKnot(2, 3, 0.15f, 64, 8);
  EXPECT_NEAR(meshWindingNumber(knot, Vec3(0.f, 0.f, 0.f)), 0.0, 1e-5) << "the knot's hole is outside it";
}

TEST(EdgeTopology, OpenPrimitivesHaveTheirRims) {
  EXPECT_EQ(EdgeTopology::build(makeQuad()).boundaryEdges(), 4u);
  EXPECT_EQ(EdgeTopology::build(makeQuad()).edges().size(), 5u);
  EXPECT_EQ(EdgeTopology::build(makeDisk(16)).boundaryEdges(), 16u);
  EXPECT_EQ(EdgeTopology::build(makeCylinder(16, false)).boundaryEdges(), 32u);
}

TEST(EdgeTopology, SignedZeroAndRoundingAtSeamsWeld) {
  // Two triangles of one quad with separate vertex copies: one at -0.0, one a rounding step off.
  TriangleMesh m;
  m.positions = {{-1, -1, 0}, {1, -1, 0}, {1, 1, 0}, {-1, -1, -0.f}, {1, 1.0000001f, 0}, {-1, 1, 0}};
  m.indices = {0, 1, 2, 3, 4, 5};
  EdgeTopology t = EdgeTopology::build(m);
  EXPECT_EQ(t.weldedVertices(), 4u);
  EXPECT_EQ(t.edges().size(), 5u);
  EXPECT_EQ(t.boundaryEdges(), 4u);
  // Without the tolerance the rounded copy stays apart and the diagonal opens into two boundary edges.
  EXPECT_EQ(EdgeTopology::build(m, 0.f).boundaryEdges(), 6u);
}

TEST(EdgeTopology, CreasesWhereShadingJumps) {
  // The flat-shaded box: its 12 edges are creases, the 6 face diagonals are not.
  EdgeTopology box = EdgeTopology::build(makeBox());
  EXPECT_EQ(box.edges().size(), 18u);
  EXPECT_EQ(box.creaseEdges(), 12u);
  // Smooth normals: no creases on the sphere; the capped cylinder's rims are creases (cap normals
  // differ from the side's), its phi = 0 seam is not.
  EXPECT_EQ(EdgeTopology::build(makeSphere(16)).creaseEdges(), 0u);
  EXPECT_EQ(EdgeTopology::build(makeCylinder(24, true)).creaseEdges(), 48u);
}

TEST(EdgeTopology, SilhouettesFromAViewpoint) {
  TriangleMesh box = makeBox();
  EdgeTopology t = EdgeTopology::build(box);
  auto normals = faceNormals(box);
  // From far along +z, the silhouette is the rim of the +z face.
  size_t count = 0;
  for (const auto& e : t.edges())
    if (EdgeTopology::silhouetteFrom(e, box, normals, Vec3(0, 0, 10))) {
      ++count;
      EXPECT_EQ(box.positions[e.v0].z, 1.f);
      EXPECT_EQ(box.positions[e.v1].z, 1.f);
    }
  EXPECT_EQ(count, 4u);
  // A sphere from far along a direction: a closed ring of edges near the great circle at right
  // angles to it (within one ring's spacing).
  TriangleMesh sphere = makeSphere(32);
  EdgeTopology ts = EdgeTopology::build(sphere);
  auto ns = faceNormals(sphere);
  Vec3 dir = normalize(Vec3(1, 2, 3));
  std::vector<int> degree(ts.weldedVertices(), 0);
  count = 0;
  for (const auto& e : ts.edges()) {
    if (!EdgeTopology::silhouetteFrom(e, sphere, ns, dir * 1000.f)) continue;
    ++count;
    EXPECT_LT(std::abs(dot(sphere.positions[e.v0], dir)), 0.1f);
    ++degree[ts.welded(e.v0)];
    ++degree[ts.welded(e.v1)];
  }
  EXPECT_GT(count, 32u);
  for (int d : degree) EXPECT_TRUE(d == 0 || d % 2 == 0) << "the silhouette is not closed";
}

}  // namespace
}  // namespace invr
