// The primary boundary term of shape derivatives (Wang et al. 2023, §5, Eq. 9-11): what a pixel
// sees changes where edges of moving meshes sweep across the film. With the box pixel filter a
// pixel's value is the mean of radiance over its square, so by Reynolds transport
//     dI_p/dtheta = ∮_{edges in p} (L(x - eps n) - L(x + eps n)) (v(x) . n) dl,
// with n the edge's unit normal on the film, v the edge point's film velocity. The pixel's own
// border does not move with theta, so there is no separate pixel-boundary term (the issue's
// "pixel filter handled" option; we do not use the antithetic variant of §6).
//
// Candidate edges are the silhouette (from the eye), crease and, on smooth meshes, shadow
// terminator edges (terminatorJumpBound) of moving meshes (of every mesh when the view's camera
// moves: its parameters take -n . J D(x) for the camera's velocity field D), clipped to
// the near plane and the film; a sample picks an edge proportionally to its clipped film length
// times a bound on its radiance jump (creaseJumpBound), and a point uniformly along that length,
// then traces one camera sample on
// each side with the job's interior estimator (PT, RIS or ReSTIR with the previous step's
// reservoirs as neighbours: Alg. 5), and weighs the difference by dLoss/dI of the pixel it falls
// in. An edge point hidden from the camera is skipped (a ray towards it, stopped just short of
// it): both sides would see what lies in front, whose small change across the two sides is not
// the edge's jump.
#pragma once

#include <atomic>
#include <vector>

#include "core/diff/boundary_sampling.h"
#include "core/diff/boundary_term.h"

namespace invr {

inline constexpr StreamId kPrimaryBoundaryStream{12};  // pinned: the stream its documented figures used (BoundaryTermKind::pinnedStream)

// The primary term's options (optimization.boundary.terms.primary).
struct PrimaryBoundaryOptions : BoundaryTermOptionsOf<PrimaryBoundaryOptions> {
  static constexpr const char* kTerm = "primary";
  // Smooth meshes' shadow-terminator candidates (terminatorJumpBound); false is an ablation that
  // measures their share.
  bool terminators = true;
  // The side offsets, in float roundings of the edge point on the film: the first offset and the
  // smallest it shrinks to. Jobs keep these; tests vary them to measure the estimate's dependence.
  double sideOffsetRoundings = 4.0, minSideOffsetRoundings = 0.25;
};

class PrimaryBoundary final : public BoundaryTerm {
 public:
  // topology[m] for every mesh the registry moves (others may be empty).
  PrimaryBoundary(const Scene& scene, const ParameterRegistry& params, const std::vector<EdgeTopology>& topology,
                  const PrimaryBoundaryOptions& options = {});

  // Adds adjoint-weighted edge samples for one view into its gradient. `adjoint` is dLoss/dI per
  // pixel and channel (every pixel traced); both sides are traced with the view's estimator.
  BoundaryPassStats run(const BoundaryView& view) override;

  // The importance of a candidate edge per unit film length: 1 for silhouettes, boundary edges and
  // the creases of smooth meshes (split normals), whose radiance may jump by anything; for a crease
  // between two flat faces, |n0 - n1|, the turn of the shading normal across it, which bounds a
  // diffuse jump (the cosine changes by at most that), clamped to [kMinCreaseWeight, 1]. On a fine
  // flat mesh most candidate length is creases between nearly coplanar facets; picked by length
  // alone, fewer samples are left for the silhouettes (docs/shapes.md, "A fine
  // mesh's pose": 1.4-1.9x lower standard error for ReSTIR there).
  static float creaseJumpBound(Vec3 n0, Vec3 n1);
  static constexpr float kMinCreaseWeight = 1e-3f;

  // A smooth mesh's shadow terminator: direct light is zero on a face turned away from the light
  // before any shadow ray (bsdfTowards), while the interpolated normal of its lit neighbour still
  // faces the light, so an edge between a face that a light reaches and one it cannot is a
  // radiance jump that moves with the mesh (Issue 59). For an edge with two faces of mesh m (face
  // normals `faceNormals`, current pose): a bound on that jump per unit radiance, > 0 if some light
  // may light one face and not the other, else 0. Point and spot lights: exactly the edges whose
  // faces differ in the sign of ng . (l - p). Area lights: conservatively, unless both faces see
  // every corner of the emitter (its vertices, or its bounding box's corners beyond 8 vertices) or
  // neither sees any. Environments: every edge whose faces are not coplanar (each face's
  // hemisphere cuts the sky). The bound is the lit side's shading cosine towards the light at the
  // edge's ends and middle (environments: creaseJumpBound of the face normals), in
  // [kMinCreaseWeight, 1]; it only weights the sampling, so a loose one costs variance, not bias.
  static float terminatorJumpBound(const Scene& scene, uint32_t mesh, const MeshEdge& e, const std::vector<Vec3>& faceNormals);

  // Why an edge is a candidate, and its weight per unit film length (before clipping and the
  // visibility of its points). Tests read the set; run() samples it.
  enum class EdgeKind : uint8_t { Silhouette, Crease, Terminator };
  struct Candidate {
    uint32_t mesh = 0;
    size_t edge = 0;  // index into topology[mesh].edges()
    EdgeKind kind = EdgeKind::Silhouette;
    float jumpBound = 1.f;
  };
  // Creases and terminators whose two faces a closed, consistently wound mesh seen from outside
  // turns away from the eye are left out (never seen: exact), and counted in *hiddenSkipped.
  std::vector<Candidate> candidates(int view, size_t* hiddenSkipped = nullptr) const;

  // Counters of the step (GradientStats.boundary["primary"].counters): terminator_edges (clipped
  // candidates, summed over views) and hidden_edges_skipped.
  void endStep(RayStats& rays, std::vector<std::pair<std::string, uint64_t>>& counters) override;

  // The camera-to-edge segment tested for occluders ends this fraction of its length short of the
  // edge point, so a face of the edge, however grazing, is not taken for one.
  static constexpr float kVisibilitySlack = 1e-3f;

 private:
  const Scene& scene_;
  const ParameterRegistry& params_;
  const std::vector<EdgeTopology>& topology_;
  bool terminators_;
  // How far off the edge the two sides are sampled: this many times the film image of the edge
  // point's float rounding (2^-23 (1 + max |P_i|) times the film's pixels per unit length there;
  // about 4e-6 px on the knot's 64 x 48 film), film positions and ray directions in double; and the
  // smallest it shrinks to where a face next to the edge is thinner.
  double sideOffsetRoundings_, minSideOffsetRoundings_;
  uint64_t terminatorEdges_ = 0, hiddenSkipped_ = 0;
};

}  // namespace invr
