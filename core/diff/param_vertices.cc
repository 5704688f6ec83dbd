// shapes/<name>/vertices: x, y, z of every vertex of a shape's mesh, in world space, starting at
// the mesh as described (Mitsuba: <id>.vertex_positions, <id>.positions). Vertices at one position
// (the copies at uv or normal seams) are one vertex, welded as the edge topology welds them, so
// seams never open. Not with the shape's (or its group's) pose parameters. Smooth meshes keep
// their shading: their vertex normals are recomputed from the positions after every update
// (Scene::deformMesh) and differentiated through (ParameterRegistry::foldNormalAdjoints).
#include <limits>

#include "core/diff/parameter_kind.h"
#include "core/error.h"
#include "core/geometry/edge_topology.h"

namespace invr {

namespace {

// The parameter's vertices: one per welded position of the mesh.
ParameterTables::VertexField weldedVertices(const TriangleMesh& m) {
  const EdgeTopology topology = EdgeTopology::build(m);
  ParameterTables::VertexField field;
  field.weld.resize(m.positions.size());
  field.representative.assign(topology.weldedVertices(), UINT32_MAX);
  for (uint32_t v = 0; v < m.positions.size(); ++v) {
    const uint32_t w = topology.welded(v);
    field.weld[v] = w;
    if (field.representative[w] == UINT32_MAX) field.representative[w] = v;
  }
  for (const MeshEdge& e : topology.edges()) field.edges.emplace_back(topology.welded(e.v0), topology.welded(e.v1));
  return field;
}

class VerticesKind final : public ParameterKind {
 public:
  const char* name() const override { return "vertices"; }
  std::vector<std::string> groups() const override { return {"shapes"}; }
  std::string property() const override { return "vertices"; }
  std::string usage() const override { return "shapes/<name>/vertices"; }
  // groups/<g>/vertices too, to say where vertices are.
  bool claims(const std::vector<std::string>& parts) const override {
    return parts.size() >= 3 && (parts[0] == "shapes" || parts[0] == "groups") && parts[2] == "vertices";
  }

  ParameterSlot bind(const Scene& scene, const ParameterName& n, const ParameterOptions&, const ParameterTables& tables,
                     const std::vector<ParameterSlot>&) const override {
    if (n.parts[0] == "groups") failParameter(n.given, "vertices are a parameter of a shape, not of a group (shapes/<name>/vertices)");
    if (n.parts.size() != 3) failParameter(n.given, "expected " + usage());
    const int shape = meshIndex(scene, n.parts[1]);
    if (shape < 0) failParameter(n.given, "no shape named '" + n.parts[1] + "'" + closestName(n.parts[1], scene.meshNames));
    const uint32_t mesh = uint32_t(shape);
    if (scene.meshLight[mesh] >= 0)
      failParameter(n.given, "shape '" + scene.meshNames[mesh] + "' emits light ('" + scene.lights[size_t(scene.meshLight[mesh])].name +
                                 "'): moving emitters is not supported yet");
    if (tables.deforms(mesh)) failParameter(n.given, "the vertices of shape '" + scene.meshNames[mesh] + "' are listed twice");
    if (tables.moves(mesh))
      failParameter(n.given, "shape '" + scene.meshNames[mesh] +
                                 "' already moves with a pose parameter (shapes/.../translation, rotation, scale or its group's); "
                                 "a mesh moves rigidly or vertex by vertex, not both");
    const TriangleMesh& m = scene.meshes[mesh];
    if (m.positions.empty()) failParameter(n.given, "shape '" + scene.meshNames[mesh] + "' has no vertices");
    ParameterSlot slot;
    slot.shape = shape;
    slot.channels = 3;
    // The weld is built again when the slot is attached: binding only needs its size.
    slot.size = uint32_t(3 * EdgeTopology::build(m).weldedVertices());
    slot.lower = -std::numeric_limits<float>::infinity();
    slot.upper = std::numeric_limits<float>::infinity();
    // A step of a thousandth of the scene's size: vertices move in the scene's units.
    slot.learningRate = 1e-3f * 2.f * scene.radius;
    return slot;
  }
  void attach(const Scene& scene, const ParameterSlot& slot, ParameterTables& t) const override {
    const uint32_t mesh = uint32_t(slot.shape);
    const TriangleMesh& m = scene.meshes[mesh];
    ParameterTables::VertexField field = weldedVertices(m);
    field.offset = slot.offset;
    field.mesh = mesh;
    if (!m.normals.empty()) {  // smooth: dL/d(vertex normals) gathered beside theta, folded in later
      field.normalOffset = int64_t(t.normalAdjoints);
      t.normalAdjoints += 3 * m.positions.size();
    }
    if (t.vertexField.size() < scene.meshes.size()) t.vertexField.resize(scene.meshes.size(), -1);
    t.vertexField[mesh] = int(t.vertexFields.size());
    t.vertexFields.push_back(std::move(field));
    t.markMoving(scene, mesh);
  }
  void read(const Scene& scene, const ParameterSlot& s, const ParameterTables& t, float* out) const override {
    const ParameterTables::VertexField& f = t.vertices(uint32_t(s.shape));
    const auto& pos = scene.meshes[size_t(s.shape)].positions;
    for (size_t w = 0; w < f.representative.size(); ++w)
      for (int c = 0; c < 3; ++c) out[3 * w + size_t(c)] = pos[f.representative[w]][c];
  }
  void write(const float* in, const ParameterSlot& s, const ParameterTables& t, Scene& scene, bool, SceneChanges&) const override {
    const ParameterTables::VertexField& f = t.vertices(uint32_t(s.shape));
    std::vector<Vec3> positions(f.weld.size());
    for (size_t v = 0; v < positions.size(); ++v) {
      const float* xyz = in + 3 * size_t(f.weld[v]);
      positions[v] = Vec3(xyz[0], xyz[1], xyz[2]);
    }
    scene.deformMesh(uint32_t(s.shape), positions, &f.weld);
  }
  void offer(const Scene& scene, std::vector<OfferedName>& out) const override {
    for (size_t m = 0; m < scene.meshNames.size(); ++m)
      out.push_back({"shapes/" + scene.meshNames[m] + "/vertices", {scene.meshNames[m] + ".vertex_positions"}, int(m)});
  }
  std::string fromMitsuba(const Scene& scene, const std::vector<std::string>& owner, const std::string& prop, bool) const override {
    if (prop != "vertex_positions" && prop != "positions") return "";  // mi.traverse: a mesh's vertex buffer
    if (owner.size() != 1 || meshIndex(scene, owner[0]) < 0) {
      std::string key;
      for (const auto& o : owner) key += o + ".";
      throw InputError("parameter '" + key + prop + "' (a Mitsuba name): no shape (mesh) with id '" + owner[0] + "'");
    }
    return "shapes/" + owner[0] + "/vertices";
  }
  std::string mitsubaProperties() const override { return "vertex_positions or positions of a mesh"; }
  bool relativeToGeometry() const override { return true; }
  bool isMesh() const override { return true; }
};

const RegisterParameterKind kVertices(33, std::make_unique<VerticesKind>());

}  // namespace

TriangleMesh ParameterRegistry::vertexMesh(const Scene& scene, const ParameterSlot& slot, const float* values) const {
  const ParameterTables::VertexField& f = t_.vertices(uint32_t(slot.shape));
  TriangleMesh out;
  out.positions.resize(f.representative.size());
  for (size_t w = 0; w < out.positions.size(); ++w) out.positions[w] = Vec3(values[3 * w], values[3 * w + 1], values[3 * w + 2]);
  const TriangleMesh& m = scene.meshes[size_t(slot.shape)];
  for (size_t t = 0; t < m.triangleCount(); ++t) {
    const uint32_t a = f.weld[m.indices[3 * t]], b = f.weld[m.indices[3 * t + 1]], c = f.weld[m.indices[3 * t + 2]];
    if (a == b || b == c || a == c) continue;
    out.indices.insert(out.indices.end(), {a, b, c});
  }
  if (!m.normals.empty()) computeSmoothNormals(out);  // smooth meshes written smooth
  return out;
}

}  // namespace invr
