#include "core/scene/scene_builder.h"

#include <algorithm>
#include <limits>
#include <map>
#include <set>

#include "core/error.h"
#include "core/image/procedural.h"
#include "core/io/job_io.h"
#include "core/io/mesh_io.h"
#include "core/scene/zoo.h"

namespace invr {

namespace v1 = invr::v1;

std::filesystem::path AssetResolver::resolve(const v1::AssetRef& ref, const std::string& field) const {
  switch (ref.source_case()) {
    case v1::AssetRef::kPath: {
      if (ref.path().empty()) throw InputError(field + ".path: empty");
      std::filesystem::path p(ref.path());
      return p.is_absolute() ? p : baseDir / p;
    }
    case v1::AssetRef::kSha256:
      if (!byHash) throw InputError(field + ".sha256: content-hash assets need the service (use 'path' for local files)");
      return byHash(ref.sha256());
    default: throw InputError(field + ": set either 'path' or 'sha256'");
  }
}

namespace {

[[noreturn]] void fail(const std::string& field, const std::string& why) { throw InputError(field + ": " + why); }

Vec3 vec(const v1::Vec3& v, const std::string& field) {
  Vec3 r(float(v.x()), float(v.y()), float(v.z()));
  if (!std::isfinite(v.x()) || !std::isfinite(v.y()) || !std::isfinite(v.z())) fail(field, "not a finite vector");
  return r;
}

Vec3 boundsCentre(const std::vector<Vec3>& points) {
  Vec3 lo(std::numeric_limits<float>::infinity()), hi = -lo;
  for (const auto& p : points) { lo = vmin(lo, p); hi = vmax(hi, p); }
  return (lo + hi) * 0.5f;
}

Rgb rgb(const v1::Rgb& c, const std::string& field) {
  if (!std::isfinite(c.r()) || !std::isfinite(c.g()) || !std::isfinite(c.b())) fail(field, "not a finite colour");
  if (c.r() < 0 || c.g() < 0 || c.b() < 0) fail(field, "colour components must not be negative");
  return Rgb(float(c.r()), float(c.g()), float(c.b()));
}

float optionalScale(bool has, double v, const std::string& field) {
  if (!has) return 1.f;
  if (!std::isfinite(v) || v < 0) fail(field, "must be a finite number >= 0");
  return float(v);
}

Affine transformOf(const v1::Transform& t, const std::string& field) {
  Vec3 s = t.has_scale() ? vec(t.scale(), field + ".scale") : Vec3(1.f);
  if (s.x == 0.f || s.y == 0.f || s.z == 0.f) fail(field + ".scale", "components must be non-zero");
  Vec3 r = vec(t.rotate_xyz_degrees(), field + ".rotate_xyz_degrees");
  Vec3 tr = vec(t.translate(), field + ".translate");
  Affine trs = Affine::translate(tr) * Affine::rotate(2, r.z) * Affine::rotate(1, r.y) * Affine::rotate(0, r.x) * Affine::scale(s);
  if (t.matrix_size() == 0) return trs;
  if (t.matrix_size() != 12 && t.matrix_size() != 16)
    fail(field + ".matrix", "needs 12 numbers (3 rows of 4) or 16 (4 rows of 4), got " + std::to_string(t.matrix_size()));
  for (int i = 0; i < t.matrix_size(); ++i)
    if (!std::isfinite(t.matrix(i))) fail(field + ".matrix", "element " + std::to_string(i) + " is not a finite number");
  if (t.matrix_size() == 16 && (t.matrix(12) != 0 || t.matrix(13) != 0 || t.matrix(14) != 0 || t.matrix(15) != 1))
    fail(field + ".matrix", "the last row must be 0 0 0 1 (projective transforms are not supported)");
  Affine m;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 4; ++j) m.m[i][j] = float(t.matrix(i * 4 + j));
  double det = double(m.m[0][0]) * (double(m.m[1][1]) * m.m[2][2] - double(m.m[1][2]) * m.m[2][1]) -
               double(m.m[0][1]) * (double(m.m[1][0]) * m.m[2][2] - double(m.m[1][2]) * m.m[2][0]) +
               double(m.m[0][2]) * (double(m.m[1][0]) * m.m[2][1] - double(m.m[1][1]) * m.m[2][0]);
  if (!(std::abs(det) > 1e-12)) fail(field + ".matrix", "is singular (its 3x3 part has determinant " + std::to_string(det) + ")");
  return m * trs;
}

std::shared_ptr<Image> loadTextureImage(const v1::Texture& t, const AssetResolver& assets, const std::string& field,
                                              bool colour) {
  if (t.has_procedural()) {
    const auto& p = t.procedural();
    ProceduralSpec spec;
    spec.pattern = p.pattern();
    spec.width = p.width() > 0 ? p.width() : 64;
    spec.height = p.height() > 0 ? p.height() : spec.width;
    if (p.has_color_a()) spec.a = rgb(p.color_a(), field + ".procedural.color_a");
    if (p.has_color_b()) spec.b = rgb(p.color_b(), field + ".procedural.color_b");
    spec.seed = p.seed();
    const int side = inputLimits().maxImageSide;
    if (spec.width > side || spec.height > side)
      throw ResourceError(field + ".procedural: " + std::to_string(spec.width) + "x" + std::to_string(spec.height) + " texels (limit " +
                          std::to_string(side) + " per side)");
    if (assets.budget) assets.budget->charge(uint64_t(spec.width) * uint64_t(spec.height) * 3 * sizeof(float), field + ".procedural");
    try {
      return std::make_shared<Image>(makeProceduralImage(spec));
    } catch (const InputError& e) {
      rethrowWithMessage(e, field + ".procedural: " + e.what());
    }
  }
  auto path = assets.resolve(t.image(), field + ".image");
  try {
    auto img = std::make_shared<Image>(readImage(path, t.has_srgb() ? t.srgb() : colour, assets.budget));
    for (float v : img->data())
      if (!std::isfinite(v)) fail(field + ".image", "'" + path.string() + "' contains non-finite texels");
    return img;
  } catch (const InputError& e) {
    std::string what = e.what();
    if (what.rfind(field, 0) == 0) throw;
    rethrowWithMessage(e, field + ".image: " + what);
  }
}

Texture texture(const v1::Texture& t, const AssetResolver& assets, const std::string& field, bool colour, Rgb dflt) {
  float scale = optionalScale(t.has_scale(), t.scale(), field + ".scale");
  switch (t.source_case()) {
    case v1::Texture::kConstant: return Texture(rgb(t.constant(), field + ".constant") * scale);
    case v1::Texture::kValue:
      if (!std::isfinite(t.value()) || t.value() < 0) fail(field + ".value", "must be a finite number >= 0");
      return Texture(Rgb(float(t.value()) * scale));
    case v1::Texture::kImage:
    case v1::Texture::kProcedural: return Texture(loadTextureImage(t, assets, field, colour), scale);
    default: return Texture(dflt * scale);
  }
}

void checkRoughness(const Texture& t, const std::string& field) {
  auto ok = [](float a) { return std::isfinite(a) && a > 0.f && a <= 1.f; };
  if (t.isConstant()) {
    if (!ok(t.constant().x)) fail(field, "GGX roughness must be in (0, 1] (got " + std::to_string(t.constant().x) + ")");
  } else {
    for (int y = 0; y < t.image()->height(); ++y)
      for (int x = 0; x < t.image()->width(); ++x)
        if (!ok(t.image()->at(x, y, 0))) fail(field, "GGX roughness texels must be in (0, 1]");
  }
}

Material material(const v1::Material& m, const AssetResolver& assets, const std::string& field) {
  Material out;
  out.name = m.name();
  out.oneSided = m.one_sided();
  out.aliases.assign(m.aliases().begin(), m.aliases().end());
  switch (m.kind_case()) {
    case v1::Material::kDiffuse:
      out.kind = BsdfKind::Diffuse;
      out.albedo = texture(m.diffuse().albedo(), assets, field + ".diffuse.albedo", true, Rgb(0.5f));
      break;
    case v1::Material::kRoughConductor: {
      const auto& c = m.rough_conductor();
      out.kind = BsdfKind::RoughConductor;
      out.roughness = texture(c.roughness(), assets, field + ".rough_conductor.roughness", false, Rgb(0.1f));
      checkRoughness(out.roughness, field + ".rough_conductor.roughness");
      // Aluminium at roughly 650/550/450 nm unless given.
      out.eta = c.has_eta() ? rgb(c.eta(), field + ".rough_conductor.eta") : Rgb(1.66f, 0.88f, 0.52f);
      out.k = c.has_k() ? rgb(c.k(), field + ".rough_conductor.k") : Rgb(8.06f, 6.35f, 4.98f);
      break;
    }
    case v1::Material::kRoughPlastic: {
      const auto& p = m.rough_plastic();
      out.kind = BsdfKind::RoughPlastic;
      out.albedo = texture(p.albedo(), assets, field + ".rough_plastic.albedo", true, Rgb(0.5f));
      out.roughness = texture(p.roughness(), assets, field + ".rough_plastic.roughness", false, Rgb(0.1f));
      checkRoughness(out.roughness, field + ".rough_plastic.roughness");
      out.ior = p.has_ior() ? float(p.ior()) : 1.5f;
      if (!(out.ior > 1.f && out.ior < 10.f)) fail(field + ".rough_plastic.ior", "must be in (1, 10)");
      break;
    }
    case v1::Material::kMirror:
      out.kind = BsdfKind::Mirror;
      out.reflectance = m.mirror().has_reflectance() ? rgb(m.mirror().reflectance(), field + ".mirror.reflectance") : Rgb(1.f);
      break;
    case v1::Material::kDielectric:
      out.kind = BsdfKind::Dielectric;
      out.ior = m.dielectric().has_ior() ? float(m.dielectric().ior()) : 1.5f;
      if (!(out.ior > 0.f && out.ior < 10.f) || out.ior == 1.f) fail(field + ".dielectric.ior", "must be in (0, 10) and not 1");
      break;
    default: fail(field, "no material kind set (diffuse, rough_conductor, rough_plastic, mirror or dielectric)");
  }
  return out;
}

// Memory a mesh takes once built: vertex attributes, indices and its share of the BVH.
void chargeMesh(const AssetResolver& assets, uint64_t vertices, uint64_t triangles, const std::string& field) {
  const InputLimits& lim = inputLimits();
  if (vertices > lim.maxMeshVertices || triangles > lim.maxMeshTriangles)
    throw ResourceError(field + ": " + std::to_string(vertices) + " vertices, " + std::to_string(triangles) + " triangles (limits " +
                        std::to_string(lim.maxMeshVertices) + ", " + std::to_string(lim.maxMeshTriangles) + ")");
  if (assets.budget) assets.budget->charge(vertices * 32 + triangles * 60, field);
}

TriangleMesh shapeMesh(const v1::Shape& s, const AssetResolver& assets, const std::string& field) {
  switch (s.geometry_case()) {
    case v1::Shape::kMesh: {
      TriangleMesh m = loadMesh(assets.resolve(s.mesh(), field + ".mesh"), assets.budget);
      chargeMesh(assets, m.positions.size(), m.triangleCount(), field + ".mesh");
      return m;
    }
    case v1::Shape::kQuad: return makeQuad();
    case v1::Shape::kBox: return makeBox();
    case v1::Shape::kSphere: {
      int rings = s.sphere().rings() > 0 ? s.sphere().rings() : 32;
      if (rings < 2 || rings > 4096) fail(field + ".sphere.rings", "must be in 2..4096");
      chargeMesh(assets, uint64_t(rings + 1) * uint64_t(2 * rings + 1), uint64_t(4) * uint64_t(rings) * uint64_t(rings), field + ".sphere");
      return makeSphere(rings);
    }
    case v1::Shape::kCylinder: {
      int seg = s.cylinder().segments() > 0 ? s.cylinder().segments() : 64;
      if (seg < 3 || seg > 65536) fail(field + ".cylinder.segments", "must be in 3..65536");
      chargeMesh(assets, uint64_t(4) * uint64_t(seg + 2), uint64_t(4) * uint64_t(seg), field + ".cylinder");
      return makeCylinder(seg, s.cylinder().capped());
    }
    case v1::Shape::kTorusKnot: {
      const auto& k = s.torus_knot();
      int seg = k.segments() > 0 ? k.segments() : 256, tube = k.tube_segments() > 0 ? k.tube_segments() : 16;
      double r = k.tube_radius() > 0 ? k.tube_radius() : 0.15;
      if (seg < 8 || tube < 3 || seg > 65536 || tube > 4096) fail(field + ".torus_knot", "segments must be in 8..65536 and tube_segments in 3..4096");
      if (!(r < 1.0)) fail(field + ".torus_knot.tube_radius", "must be in (0, 1)");
      chargeMesh(assets, uint64_t(seg + 1) * uint64_t(tube + 1), uint64_t(2) * uint64_t(seg) * uint64_t(tube), field + ".torus_knot");
      return makeTorusKnot(k.p() != 0 ? k.p() : 2, k.q() != 0 ? k.q() : 3, float(r), seg, tube);
    }
    case v1::Shape::kDisk: {
      int seg = s.disk().segments() > 0 ? s.disk().segments() : 64;
      if (seg < 3 || seg > 65536) fail(field + ".disk.segments", "must be in 3..65536");
      chargeMesh(assets, uint64_t(seg) + 1, uint64_t(seg), field + ".disk");
      return makeDisk(seg);
    }
    case v1::Shape::kHeightfield: {
      const auto& h = s.heightfield();
      const int cells = h.cells() > 0 ? h.cells() : 64;
      if (cells > 1024) fail(field + ".heightfield.cells", "must be in 1..1024");
      if (!h.has_height()) fail(field + ".heightfield.height", "needs a procedural image (e.g. pattern \"bumps\")");
      v1::Texture t;
      *t.mutable_procedural() = h.height();
      const std::shared_ptr<Image> im = loadTextureImage(t, assets, field + ".heightfield.height", false);
      chargeMesh(assets, uint64_t(cells + 1) * uint64_t(cells + 1), uint64_t(2) * uint64_t(cells) * uint64_t(cells), field + ".heightfield");
      // Bilinear in the image (texel centres at (i + 0.5) / width), channels averaged.
      auto height = [&](float u, float v) {
        const float x = std::clamp(u * float(im->width()) - 0.5f, 0.f, float(im->width() - 1));
        const float y = std::clamp(v * float(im->height()) - 0.5f, 0.f, float(im->height() - 1));
        const int x0 = int(x), y0 = int(y), x1 = std::min(x0 + 1, im->width() - 1), y1 = std::min(y0 + 1, im->height() - 1);
        const float fx = x - float(x0), fy = y - float(y0);
        auto mean = [&](int px, int py) {
          float sum = 0;
          for (int c = 0; c < im->channels(); ++c) sum += im->at(px, py, c);
          return sum / float(im->channels());
        };
        return (1 - fy) * ((1 - fx) * mean(x0, y0) + fx * mean(x1, y0)) + fy * ((1 - fx) * mean(x0, y1) + fx * mean(x1, y1));
      };
      return makeHeightfield(cells, height);
    }
    case v1::Shape::kPlant: {
      const auto& p = s.plant();
      const int leaves = p.leaves() > 0 ? p.leaves() : 100, segments = p.leaf_segments() > 0 ? p.leaf_segments() : 18;
      if (leaves > 100000) fail(field + ".plant.leaves", "must be in 1..100000");
      if (segments < 3 || segments > 256) fail(field + ".plant.leaf_segments", "must be in 3..256");
      chargeMesh(assets, plantVertexCount(leaves, segments), plantTriangleCount(leaves, segments), field + ".plant");
      return makePlant(leaves, segments, p.seed());
    }
    default: fail(field, "no geometry set (mesh, quad, box, sphere, cylinder, disk, torus_knot, heightfield or plant)");
  }
}

}  // namespace

std::unique_ptr<Scene> buildScene(const v1::Scene& spec, const AssetResolver& assets, SceneUse use) {
  auto scene = std::make_unique<Scene>();
  scene->name = spec.name();
  const std::string root = "scene";

  int w = spec.film().width() > 0 ? spec.film().width() : 256;
  int h = spec.film().height() > 0 ? spec.film().height() : w;
  if (spec.film().width() < 0 || spec.film().height() < 0) fail(root + ".film", "width and height must be positive");
  if (w > inputLimits().maxImageSide || h > inputLimits().maxImageSide)
    throw ResourceError(root + ".film: " + std::to_string(w) + "x" + std::to_string(h) + " pixels (limit " +
                        std::to_string(inputLimits().maxImageSide) + " per side)");
  scene->width = w;
  scene->height = h;

  std::map<std::string, int> materialIndex;
  for (int i = 0; i < spec.materials_size(); ++i) {
    const auto& m = spec.materials(i);
    std::string field = root + ".materials[" + std::to_string(i) + "]";
    if (m.name().empty()) fail(field + ".name", "every material needs a name");
    field += " (" + m.name() + ")";
    if (!materialIndex.emplace(m.name(), i).second) fail(field + ".name", "duplicate material name");
    scene->materials.push_back(material(m, assets, field));
  }

  std::map<std::string, int> shapeIndex;
  for (int i = 0; i < spec.shapes_size(); ++i) {
    const auto& s = spec.shapes(i);
    std::string field = root + ".shapes[" + std::to_string(i) + "]";
    if (s.name().empty()) fail(field + ".name", "every shape needs a name");
    field += " (" + s.name() + ")";
    if (!shapeIndex.emplace(s.name(), i).second) fail(field + ".name", "duplicate shape name");
    auto mit = materialIndex.find(s.material());
    if (mit == materialIndex.end()) fail(field + ".material", "unknown material '" + s.material() + "'");
    Affine xf = transformOf(s.transform(), field + ".transform");
    TriangleMesh mesh;
    try {
      mesh = shapeMesh(s, assets, field);
    } catch (const InputError& e) {
      std::string what = e.what();
      if (what.rfind(field, 0) == 0) throw;
      rethrowWithMessage(e, field + ": " + what);
    }
    if (s.face_normals() && s.smooth_normals()) fail(field, "face_normals and smooth_normals exclude each other");
    if (s.face_normals()) mesh.normals.clear();
    if (s.flip_tex_coords())
      for (auto& uv : mesh.uvs) uv.y = 1.f - uv.y;
    mesh.transform(xf);
    if (s.flip_normals()) mesh.flipWinding(true);
    validateMesh(mesh, field);
    if (s.smooth_normals() && mesh.normals.empty()) computeSmoothNormals(mesh);
    Vec3 pivot = s.has_pivot() ? vec(s.pivot(), field + ".pivot") : boundsCentre(mesh.positions);
    scene->meshPivot.push_back(pivot);
    scene->meshes.push_back(std::move(mesh));
    scene->meshNames.push_back(s.name());
    scene->meshMaterial.push_back(mit->second);
    scene->meshLight.push_back(-1);
  }

  for (int i = 0; i < spec.lights_size(); ++i) {
    const auto& l = spec.lights(i);
    std::string field = root + ".lights[" + std::to_string(i) + "]";
    if (l.name().empty()) fail(field + ".name", "every light needs a name");
    field += " (" + l.name() + ")";
    Light out;
    out.name = l.name();
    out.scale = optionalScale(l.has_scale(), l.scale(), field + ".scale");
    switch (l.kind_case()) {
      case v1::Light::kArea: {
        auto it = shapeIndex.find(l.area().shape());
        if (it == shapeIndex.end()) fail(field + ".area.shape", "unknown shape '" + l.area().shape() + "'");
        if (scene->meshLight[size_t(it->second)] >= 0) fail(field + ".area.shape", "shape '" + l.area().shape() + "' already has a light");
        out.kind = LightKind::Area;
        out.mesh = uint32_t(it->second);
        out.radiance = rgb(l.area().radiance(), field + ".area.radiance");
        out.twoSided = l.area().two_sided();
        double area = 0;
        const auto& m = scene->meshes[out.mesh];
        for (size_t t = 0; t < m.triangleCount(); ++t) area += m.triangleArea(t);
        if (!(area > 1e-12)) fail(field + ".area.shape", "zero-area light");
        scene->meshLight[out.mesh] = int(scene->lights.size());
        break;
      }
      case v1::Light::kPoint:
        out.kind = LightKind::Point;
        out.position = vec(l.point().position(), field + ".point.position");
        out.intensity = rgb(l.point().intensity(), field + ".point.intensity");
        break;
      case v1::Light::kSpot: {
        const auto& s = l.spot();
        out.kind = LightKind::Spot;
        out.position = vec(s.position(), field + ".spot.position");
        Vec3 target = vec(s.target(), field + ".spot.target");
        if (lengthSquared(target - out.position) == 0.f) fail(field + ".spot.target", "must differ from position");
        out.direction = normalize(target - out.position);
        out.intensity = rgb(s.intensity(), field + ".spot.intensity");
        double outer = s.cone_outer_degrees() > 0 ? s.cone_outer_degrees() : 30.0;
        double inner = s.cone_inner_degrees() > 0 ? s.cone_inner_degrees() : 0.8 * outer;
        if (!(outer < 180.0)) fail(field + ".spot.cone_outer_degrees", "must be in (0, 180)");
        if (!(inner <= outer)) fail(field + ".spot.cone_inner_degrees", "must not exceed cone_outer_degrees");
        out.cosOuter = float(std::cos(outer * M_PI / 180.0));
        out.cosInner = float(std::cos(inner * M_PI / 180.0));
        if (out.cosInner <= out.cosOuter) out.cosInner = std::nextafter(out.cosOuter, 1.f);
        break;
      }
      case v1::Light::kEnvironment: {
        const auto& t = l.environment().radiance();
        if (!t.has_image() && !t.has_procedural()) fail(field + ".environment.radiance", "needs an image or procedural texture (use constant_environment for a constant)");
        out.kind = LightKind::Environment;
        out.envImage = loadTextureImage(t, assets, field + ".environment.radiance", true);
        if (t.has_scale()) out.scale *= optionalScale(true, t.scale(), field + ".environment.radiance.scale");
        buildEnvironmentDistribution(out);
        {
          const double a = l.environment().rotate_y_degrees();
          if (!std::isfinite(a)) fail(field + ".environment.rotate_y_degrees", "must be a finite angle");
          out.envCosY = float(std::cos(a * M_PI / 180.0));
          out.envSinY = float(std::sin(a * M_PI / 180.0));
        }
        break;
      }
      case v1::Light::kConstantEnvironment:
        out.kind = LightKind::ConstantEnvironment;
        out.radiance = rgb(l.constant_environment().radiance(), field + ".constant_environment.radiance");
        break;
      default: fail(field, "no light kind set (area, point, spot, environment or constant_environment)");
    }
    scene->lights.push_back(std::move(out));
  }

  if (spec.views_size() == 0) fail(root + ".views", "at least one camera view is required");
  // Stored ReSTIR reservoirs record their view in 16 bits.
  if (spec.views_size() > 65535) fail(root + ".views", "at most 65535 camera views are supported");
  for (int i = 0; i < spec.views_size(); ++i) {
    const auto& c = spec.views(i);
    std::string field = root + ".views[" + std::to_string(i) + "]";
    Vec3 eye = vec(c.eye(), field + ".eye"), target = vec(c.target(), field + ".target");
    Vec3 up = c.has_up() ? vec(c.up(), field + ".up") : Vec3(0, 1, 0);
    if (lengthSquared(target - eye) == 0.f) fail(field + ".target", "must differ from eye");
    if (lengthSquared(cross(normalize(target - eye), up)) < 1e-8f) fail(field + ".up", "must not be parallel to the view direction");
    double fov = c.fov_y_degrees() != 0 ? c.fov_y_degrees() : 40.0;
    if (!(fov > 0 && fov < 180)) fail(field + ".fov_y_degrees", "must be in (0, 180)");
    Camera cam = Camera::lookAt(eye, target, up, float(fov));
    cam.name = c.name();
    scene->cameras.push_back(cam);
  }
  scene->meshGroup.assign(scene->meshes.size(), -1);
  std::map<std::string, int> groupIndex;
  for (int i = 0; i < spec.groups_size(); ++i) {
    const auto& g = spec.groups(i);
    std::string field = root + ".groups[" + std::to_string(i) + "]";
    if (g.name().empty()) fail(field + ".name", "every group needs a name");
    field += " (" + g.name() + ")";
    if (!groupIndex.emplace(g.name(), i).second) fail(field + ".name", "duplicate group name");
    if (g.shapes_size() == 0) fail(field + ".shapes", "a group needs at least one shape");
    Scene::Group out;
    out.name = g.name();
    std::vector<Vec3> corners;
    for (int k = 0; k < g.shapes_size(); ++k) {
      const std::string sf = field + ".shapes[" + std::to_string(k) + "]";
      auto it = shapeIndex.find(g.shapes(k));
      if (it == shapeIndex.end()) fail(sf, "unknown shape '" + g.shapes(k) + "'");
      int& owner = scene->meshGroup[size_t(it->second)];
      if (owner == i) fail(sf, "shape '" + g.shapes(k) + "' is listed twice");
      if (owner >= 0) fail(sf, "shape '" + g.shapes(k) + "' is already in group '" + spec.groups(owner).name() + "' (a shape belongs to at most one group)");
      owner = i;
      out.meshes.push_back(uint32_t(it->second));
      const auto& positions = scene->meshes[size_t(it->second)].positions;
      corners.insert(corners.end(), positions.begin(), positions.end());
    }
    out.pivot = g.has_pivot() ? vec(g.pivot(), field + ".pivot") : boundsCentre(corners);
    scene->groups.push_back(std::move(out));
  }
  scene->finalize(use == SceneUse::Render);
  return scene;
}

TriangleMesh startMesh(const v1::MeshStart& start, const v1::Shape& shape, const TriangleMesh& truth, const AssetResolver& assets,
                       const std::string& field) {
  TriangleMesh m;
  Vec3 lo(std::numeric_limits<float>::infinity()), hi = -lo;
  for (const Vec3& p : truth.positions) { lo = vmin(lo, p); hi = vmax(hi, p); }
  const Vec3 centre = (lo + hi) * 0.5f, size = hi - lo;
  switch (start.start_case()) {
    case v1::MeshStart::kFile: {
      try {
        m = loadMesh(assets.resolve(start.file(), field + ".file"), assets.budget);
      } catch (const InputError& e) {
        std::string what = e.what();
        if (what.rfind(field, 0) == 0) throw;
        rethrowWithMessage(e, field + ".file: " + what);
      }
      chargeMesh(assets, m.positions.size(), m.triangleCount(), field + ".file");
      m.transform(transformOf(shape.transform(), field + " (the shape's transform)"));
      break;
    }
    case v1::MeshStart::kSphere: {
      const int n = start.sphere().subdivisions() > 0 ? start.sphere().subdivisions() : 3;
      if (n > 7) fail(field + ".sphere.subdivisions", "must be in 1..7 (0: 3); 7 gives 163842 vertices");
      chargeMesh(assets, uint64_t(10) * (uint64_t(1) << (2 * n)) + 2, uint64_t(20) * (uint64_t(1) << (2 * n)), field + ".sphere");
      m = makeIcosphere(n);
      const float r = 0.5f * std::max({size.x, size.y, size.z});
      for (Vec3& p : m.positions) p = centre + p * r;
      break;
    }
    case v1::MeshStart::kPlane: {
      const int n = start.plane().subdivisions() > 0 ? start.plane().subdivisions() : 16;
      if (n > 1024) fail(field + ".plane.subdivisions", "must be in 1..1024 (0: 16)");
      chargeMesh(assets, uint64_t(n + 1) * uint64_t(n + 1), uint64_t(2) * uint64_t(n) * uint64_t(n), field + ".plane");
      m = makeGrid(n);
      // Across the two largest sides, facing along the smallest (right-handed: u x v = normal).
      int k = 0;
      for (int a = 1; a < 3; ++a)
        if (size[a] < size[k]) k = a;
      const int u = (k + 1) % 3, v = (k + 2) % 3;
      for (Vec3& p : m.positions) {
        Vec3 q = centre;
        q[u] += 0.5f * size[u] * p.x;
        q[v] += 0.5f * size[v] * p.y;
        p = q;
      }
      break;
    }
    default: fail(field, "set file, sphere or plane");
  }
  m.normals.clear();
  m.uvs.clear();
  validateMesh(m, field);
  // Shaded as the shape is: smooth when it has vertex normals (recomputed from the positions as
  // the mesh deforms), else flat.
  if (!truth.normals.empty()) computeSmoothNormals(m);
  return m;
}

v1::Scene jobSceneSpec(const v1::JobSpec& job) {
  switch (job.scene_source_case()) {
    case v1::JobSpec::kZoo: return zooScene(job.zoo());
    case v1::JobSpec::kScene: return job.scene();
    default: buildJobScene(job); return {};  // throws the reason
  }
}

std::unique_ptr<Scene> buildJobScene(const v1::JobSpec& job, const AssetResolver& assets, SceneUse use) {
  switch (job.scene_source_case()) {
    case v1::JobSpec::kZoo: return buildScene(zooScene(job.zoo()), assets, use);
    case v1::JobSpec::kScene: return buildScene(job.scene(), assets, use);
    case v1::JobSpec::kMitsuba:
      throw InputError("mitsuba: a Mitsuba scene is imported into 'scene' by the client (invr render, optimize, run, submit and plan do it); "
                       "import it first (invr import) to use the job elsewhere");
    default: throw InputError("job: set 'zoo' (a built-in scene name), 'scene' or 'mitsuba' (a Mitsuba 3 scene file)");
  }
}


}  // namespace invr
