#include "core/scene/mitsuba_export.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <map>
#include <set>
#include <sstream>

#include "core/error.h"
#include "core/image/image.h"
#include "core/io/mesh_io.h"

namespace invr {

namespace fs = std::filesystem;

namespace {

constexpr double kPiD = 3.14159265358979323846;

std::string num(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.9g", v);  // float round trip
  return buf;
}
std::string triple(Vec3 v) { return num(v.x) + ", " + num(v.y) + ", " + num(v.z); }
std::string rgbText(Rgb c) { return num(c.x) + ", " + num(c.y) + ", " + num(c.z); }

std::string xmlEscape(const std::string& s) {
  std::string out;
  for (char c : s) {
    switch (c) {
      case '&': out += "&amp;"; break;
      case '<': out += "&lt;"; break;
      case '>': out += "&gt;"; break;
      case '"': out += "&quot;"; break;
      case '\'': out += "&apos;"; break;
      default: out += c;
    }
  }
  return out;
}

// A file name from an object's name: letters, digits, '-', '_' and '.', unique in `taken`.
std::string fileStem(const std::string& name, const std::string& fallback, std::set<std::string>& taken) {
  std::string s;
  for (char c : name) s += (std::isalnum(static_cast<unsigned char>(c)) || c == '-' || c == '_' || c == '.') ? c : '_';
  if (s.empty() || s[0] == '.') s = fallback + s;
  std::string unique = s;
  for (int k = 2; !taken.insert(unique).second; ++k) unique = s + "_" + std::to_string(k);
  return unique;
}

class Writer {
 public:
  Writer(const Scene& scene, fs::path xml, const MitsubaExportOptions& o) : scene_(scene), xml_(std::move(xml)), o_(o) {
    dir_ = xml_.has_parent_path() ? xml_.parent_path() : fs::path(".");
    // One id per object, names kept where free.
    auto claim = [&](const std::string& name, const std::string& suffix, const char* kind) {
      if (name.empty()) return name;
      std::string id = name;
      for (int k = 2; ids_.count(id); ++k) id = name + "_" + suffix + (k > 2 ? std::to_string(k - 1) : "");
      ids_.insert(id);
      if (id != name) out_.renamed.push_back({std::string(kind) + "/" + name + "/", std::string(kind) + "/" + id + "/"});
      return id;
    };
    for (const Material& m : scene_.materials) materialId_.push_back(claim(m.name, "bsdf", "materials"));
    for (const Light& l : scene_.lights) lightId_.push_back(claim(l.name, "light", "lights"));
    for (size_t i = 0; i < scene_.meshes.size(); ++i) meshId_.push_back(claim(i < scene_.meshNames.size() ? scene_.meshNames[i] : "", "shape", "shapes"));
    for (const Camera& c : scene_.cameras) cameraId_.push_back(claim(c.name, "sensor", "views"));
  }

  MitsubaExport write() {
    out_.files.push_back(xml_);
    std::ostringstream x;
    x << "<?xml version=\"1.0\" encoding=\"utf-8\"?>\n"
      << "<!-- written by invr export: the scene with its optimised values; meshes in world space -->\n"
      << "<scene version=\"3.0.0\">\n";
    integrator(x);
    for (size_t v = 0; v < scene_.cameras.size(); ++v) sensor(x, scene_.cameras[v], cameraId_[v]);
    for (size_t m = 0; m < scene_.materials.size(); ++m) bsdf(x, m);
    // Lights in their order (the import keeps document order, and light selection follows it):
    // an area light as its emitting shape, after the shapes that emit nothing.
    for (size_t i = 0; i < scene_.meshes.size(); ++i)
      if (i >= scene_.meshLight.size() || scene_.meshLight[i] < 0) shape(x, i);
    for (size_t li = 0; li < scene_.lights.size(); ++li) {
      const Light& l = scene_.lights[li];
      if (l.kind == LightKind::Area) shape(x, l.mesh);
      else emitter(x, l, lightId_[li]);
    }
    x << "</scene>\n";
    std::ofstream f(xml_);
    if (!f) throw InputError("cannot write '" + xml_.string() + "'");
    f << x.str();
    if (!f.flush()) throw InputError("cannot write '" + xml_.string() + "'");
    return std::move(out_);
  }

 private:
  void note(const std::string& n) {
    if (std::find(out_.notes.begin(), out_.notes.end(), n) == out_.notes.end()) out_.notes.push_back(n);
  }

  void integrator(std::ostringstream& x) {
    // Mitsuba counts the camera segment in max_depth and roulette depth; invr counts vertices after it.
    const int depth = std::max(1, o_.maxDepth);
    x << "  <integrator type=\"path\">\n"
      << "    <integer name=\"max_depth\" value=\"" << depth + 1 << "\"/>\n"
      << "    <integer name=\"rr_depth\" value=\"" << std::max(1, o_.russianRouletteDepth) + 1 << "\"/>\n"
      << "  </integrator>\n";
  }

  void sensor(std::ostringstream& x, const Camera& c, const std::string& cid) {
    const double fovY = 2.0 * std::atan(double(c.tanHalfFovY)) * 180.0 / kPiD;
    x << "  <sensor type=\"perspective\"" << (cid.empty() ? "" : " id=\"" + xmlEscape(cid) + "\"") << ">\n"
      << "    <float name=\"fov\" value=\"" << num(fovY) << "\"/>\n"
      << "    <string name=\"fov_axis\" value=\"y\"/>\n"
      << "    <transform name=\"to_world\">\n"
      << "      <lookat origin=\"" << triple(c.eye) << "\" target=\"" << triple(c.eye + c.forward) << "\" up=\"" << triple(c.up) << "\"/>\n"
      << "    </transform>\n"
      << "    <sampler type=\"independent\"><integer name=\"sample_count\" value=\"" << std::max(1, o_.spp) << "\"/></sampler>\n"
      << "    <film type=\"hdrfilm\">\n"
      << "      <integer name=\"width\" value=\"" << scene_.width << "\"/>\n"
      << "      <integer name=\"height\" value=\"" << scene_.height << "\"/>\n"
      << "      <rfilter type=\"box\"/>\n"
      << "    </film>\n"
      << "  </sensor>\n";
  }

  // An image texture as an EXR (its scale multiplied in); `channels` 1 for roughness.
  std::string textureFile(const Texture& t, const std::string& name, int channels) {
    const Image& src = *t.image();
    Image im(src.width(), src.height(), channels);
    for (int y = 0; y < src.height(); ++y)
      for (int xx = 0; xx < src.width(); ++xx)
        for (int c = 0; c < channels; ++c) im.at(xx, y, c) = src.at(xx, y, std::min(c, src.channels() - 1)) * t.scale();
    const std::string rel = "textures/" + fileStem(name, "texture", textureNames_) + ".exr";
    fs::create_directories(dir_ / "textures");
    writeImage(dir_ / rel, im);
    out_.files.push_back(dir_ / rel);
    return rel;
  }

  void textureProp(std::ostringstream& x, const std::string& indent, const char* prop, const Texture& t, const std::string& fileName,
                   bool scalar) {
    if (t.isConstant()) {
      const Rgb c = t.constant();
      if (scalar) x << indent << "<float name=\"" << prop << "\" value=\"" << num(c.x) << "\"/>\n";
      else x << indent << "<rgb name=\"" << prop << "\" value=\"" << rgbText(c) << "\"/>\n";
      return;
    }
    x << indent << "<texture type=\"bitmap\" name=\"" << prop << "\">\n"
      << indent << "  <string name=\"filename\" value=\"" << xmlEscape(textureFile(t, fileName, scalar ? 1 : 3)) << "\"/>\n"
      << indent << "  <boolean name=\"raw\" value=\"true\"/>\n"
      << indent << "</texture>\n";
  }

  void bsdf(std::ostringstream& x, size_t index) {
    const Material& m = scene_.materials[index];
    const bool wrap = !m.oneSided && m.kind != BsdfKind::Dielectric;
    const std::string id = xmlEscape(materialId_[index]);
    std::string in = wrap ? "    " : "  ";
    if (wrap) x << "  <bsdf type=\"twosided\" id=\"" << id << "\">\n";
    const std::string idAttr = wrap ? "" : " id=\"" + id + "\"";
    switch (m.kind) {
      case BsdfKind::Diffuse:
        x << in << "<bsdf type=\"diffuse\"" << idAttr << ">\n";
        textureProp(x, in + "  ", "reflectance", m.albedo, m.name + "_reflectance", false);
        break;
      case BsdfKind::RoughPlastic:
        x << in << "<bsdf type=\"roughplastic\"" << idAttr << ">\n"
          << in << "  <string name=\"distribution\" value=\"ggx\"/>\n"
          << in << "  <float name=\"int_ior\" value=\"" << num(m.ior) << "\"/>\n"
          << in << "  <float name=\"ext_ior\" value=\"1\"/>\n";
        textureProp(x, in + "  ", "diffuse_reflectance", m.albedo, m.name + "_diffuse_reflectance", false);
        textureProp(x, in + "  ", "alpha", m.roughness, m.name + "_alpha", true);
        break;
      case BsdfKind::RoughConductor:
        x << in << "<bsdf type=\"roughconductor\"" << idAttr << ">\n"
          << in << "  <string name=\"distribution\" value=\"ggx\"/>\n"
          << in << "  <rgb name=\"eta\" value=\"" << rgbText(m.eta) << "\"/>\n"
          << in << "  <rgb name=\"k\" value=\"" << rgbText(m.k) << "\"/>\n";
        textureProp(x, in + "  ", "alpha", m.roughness, m.name + "_alpha", true);
        break;
      case BsdfKind::Mirror: {
        // invr's mirror reflects a constant fraction; a conductor with k = 0 reflects
        // ((eta - 1) / (eta + 1))^2 at normal incidence, which is what the import reads back.
        x << in << "<bsdf type=\"conductor\"" << idAttr << ">\n";
        const Rgb r = m.reflectance;
        if (r.x >= 1.f && r.y >= 1.f && r.z >= 1.f) {
          x << in << "  <string name=\"material\" value=\"none\"/>\n";
        } else {
          Rgb eta;
          for (int c = 0; c < 3; ++c) {
            const double s = std::sqrt(std::clamp(double(r[c]), 0.0, 0.999999));
            eta[c] = float((1 + s) / (1 - s));
          }
          x << in << "  <rgb name=\"eta\" value=\"" << rgbText(eta) << "\"/>\n"
            << in << "  <rgb name=\"k\" value=\"0, 0, 0\"/>\n";
          note("mirrors are written as conductors with k = 0 and the eta of their reflectance: Mitsuba adds the angle-dependent Fresnel term invr's mirror has not");
        }
        break;
      }
      case BsdfKind::Dielectric:
        x << in << "<bsdf type=\"dielectric\"" << idAttr << ">\n"
          << in << "  <float name=\"int_ior\" value=\"" << num(m.ior) << "\"/>\n"
          << in << "  <float name=\"ext_ior\" value=\"1\"/>\n";
        break;
    }
    x << in << "</bsdf>\n";
    if (wrap) x << "  </bsdf>\n";
    if (m.geometricSide) note("material '" + m.name + "' shades a moving smooth mesh by its geometric side; Mitsuba shades by the interpolated normal");
  }

  void shape(std::ostringstream& x, size_t i) {
    TriangleMesh mesh = scene_.meshes[i];
    mesh.faceNormals.clear();
    // invr's uv origin is the image's bottom-left, Mitsuba's the top-left: the file holds
    // Mitsuba's v, which the import (flip_tex_coords off for PLY) turns back into invr's.
    for (Vec2& uv : mesh.uvs) uv.y = 1.f - uv.y;
    const std::string name = i < scene_.meshNames.size() ? scene_.meshNames[i] : "";
    const std::string rel = "meshes/" + fileStem(name, "shape", meshNames_) + ".ply";
    fs::create_directories(dir_ / "meshes");
    writePly(dir_ / rel, mesh);
    out_.files.push_back(dir_ / rel);
    x << "  <shape type=\"ply\"" << (meshId_[i].empty() ? "" : " id=\"" + xmlEscape(meshId_[i]) + "\"") << ">\n"
      << "    <string name=\"filename\" value=\"" << xmlEscape(rel) << "\"/>\n";
    if (mesh.normals.empty()) x << "    <boolean name=\"face_normals\" value=\"true\"/>\n";
    const int mat = i < scene_.meshMaterial.size() ? scene_.meshMaterial[i] : -1;
    if (mat >= 0) x << "    <ref id=\"" << xmlEscape(materialId_[size_t(mat)]) << "\"/>\n";
    const int li = i < scene_.meshLight.size() ? scene_.meshLight[i] : -1;
    if (li >= 0) {
      const Light& l = scene_.lights[size_t(li)];
      x << "    <emitter type=\"area\" id=\"" << xmlEscape(lightId_[size_t(li)]) << "\">\n"
        << "      <rgb name=\"radiance\" value=\"" << rgbText(l.radiance * l.scale) << "\"/>\n"
        << "    </emitter>\n";
      if (l.twoSided) note("light '" + l.name + "' emits from both sides; Mitsuba's area emitters emit from the front only");
    }
    x << "  </shape>\n";
  }

  void emitter(std::ostringstream& x, const Light& l, const std::string& lid) {
    const std::string id = xmlEscape(lid);
    switch (l.kind) {
      case LightKind::Point:
        x << "  <emitter type=\"point\" id=\"" << id << "\">\n"
          << "    <point name=\"position\" value=\"" << triple(l.position) << "\"/>\n"
          << "    <rgb name=\"intensity\" value=\"" << rgbText(l.intensity * l.scale) << "\"/>\n"
          << "  </emitter>\n";
        break;
      case LightKind::Spot: {
        Vec3 up = std::abs(l.direction.y) < 0.9f ? Vec3(0, 1, 0) : Vec3(1, 0, 0);
        const double outer = std::acos(std::clamp(double(l.cosOuter), -1.0, 1.0)) * 180.0 / kPiD;
        double inner = std::acos(std::clamp(double(l.cosInner), -1.0, 1.0)) * 180.0 / kPiD;
        if (inner > outer - 1e-3) inner = outer;  // a hard edge (the builder keeps the cosines a hair apart)
        x << "  <emitter type=\"spot\" id=\"" << id << "\">\n"
          << "    <transform name=\"to_world\">\n"
          << "      <lookat origin=\"" << triple(l.position) << "\" target=\"" << triple(l.position + l.direction) << "\" up=\"" << triple(up)
          << "\"/>\n"
          << "    </transform>\n"
          << "    <rgb name=\"intensity\" value=\"" << rgbText(l.intensity * l.scale) << "\"/>\n"
          << "    <float name=\"cutoff_angle\" value=\"" << num(outer) << "\"/>\n"
          << "    <float name=\"beam_width\" value=\"" << num(std::min(inner, outer)) << "\"/>\n"
          << "  </emitter>\n";
        if (inner < outer) note("spot lights fall off between beam_width and cutoff_angle by invr's smooth step; Mitsuba's ramp is linear in angle");
        break;
      }
      case LightKind::ConstantEnvironment:
        x << "  <emitter type=\"constant\" id=\"" << id << "\">\n"
          << "    <rgb name=\"radiance\" value=\"" << rgbText(l.radiance * l.scale) << "\"/>\n"
          << "  </emitter>\n";
        break;
      case LightKind::Environment: {
        Texture t(l.envImage, 1.f);
        const std::string rel = textureFile(t, l.name, 3);
        // The import turns Mitsuba's map half a turn about +y onto invr's; the export undoes it.
        const double angle = std::atan2(double(l.envSinY), double(l.envCosY)) * 180.0 / kPiD - 180.0;
        x << "  <emitter type=\"envmap\" id=\"" << id << "\">\n"
          << "    <string name=\"filename\" value=\"" << xmlEscape(rel) << "\"/>\n"
          << "    <float name=\"scale\" value=\"" << num(l.scale) << "\"/>\n"
          << "    <transform name=\"to_world\"><rotate y=\"1\" angle=\"" << num(angle) << "\"/></transform>\n"
          << "  </emitter>\n";
        break;
      }
      case LightKind::Area: break;
    }
  }

  const Scene& scene_;
  fs::path xml_, dir_;
  MitsubaExportOptions o_;
  MitsubaExport out_;
  std::set<std::string> meshNames_, textureNames_, ids_;
  std::vector<std::string> materialId_, lightId_, meshId_, cameraId_;
};

}  // namespace

MitsubaExport exportMitsubaScene(const Scene& scene, const fs::path& xml, const MitsubaExportOptions& options) {
  try {
    return Writer(scene, xml, options).write();
  } catch (const fs::filesystem_error& e) {
    throw InputError("cannot write the scene beside '" + xml.string() + "': " + e.code().message());
  }
}

}  // namespace invr
