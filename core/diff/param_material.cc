// Material parameters: materials/<m>/albedo (diffuse, rough_plastic) and materials/<m>/roughness
// (rough_conductor, rough_plastic), a constant or a texture's texels (the texture's scale applied).
#include <algorithm>

#include "core/diff/parameter_kind.h"
#include "core/error.h"

namespace invr {

namespace {

class MaterialTextureKind : public ParameterKind {
 public:
  std::vector<std::string> groups() const override { return {"materials"}; }
  std::string usage() const override { return "materials/<name>/" + property(); }

  ParameterSlot bind(const Scene& scene, const ParameterName& n, const ParameterOptions&, const ParameterTables& tables,
                     const std::vector<ParameterSlot>& earlier) const override {
    if (n.parts.size() != 3) failParameter(n.given, "expected " + usage());
    const std::string& id = n.parts[1];
    const int m = materialIndex(scene, id);
    if (m < 0) {
      std::vector<std::string> names;
      for (const auto& x : scene.materials) names.push_back(x.name);
      failParameter(n.given, "no material named '" + id + "'" + closestName(id, names));
    }
    const Material& mat = scene.materials[size_t(m)];
    if (!has(mat)) failParameter(n.given, "material '" + id + "' has no " + property() + " (only " + which() + " do)");
    ParameterSlot slot;
    slot.material = m;
    defaults(slot);
    const Texture& tex = texture(mat);
    if (!tex.isConstant()) {
      if (tex.scale() == 0.f) failParameter(n.given, "texture scale is 0, so its texels cannot be recovered");
      slot.width = tex.image()->width();
      slot.height = tex.image()->height();
    }
    slot.size = uint32_t(slot.channels * (slot.width > 0 ? slot.width * slot.height : 1));
    refuseSameValue(n, ParameterTables::lookup(table(tables), m), earlier);
    return slot;
  }
  void attach(const Scene&, const ParameterSlot& slot, ParameterTables& tables) const override {
    ParameterTables::put(table(tables), size_t(slot.material), int(slot.offset));
  }
  void read(const Scene& scene, const ParameterSlot& s, const ParameterTables&, float* out) const override {
    const Texture& t = texture(scene.materials[size_t(s.material)]);
    if (t.isConstant()) {
      for (int c = 0; c < s.channels; ++c) out[c] = t.constant()[c];
      return;
    }
    const Image& im = *t.image();
    for (int y = 0; y < s.height; ++y)
      for (int x = 0; x < s.width; ++x)
        for (int c = 0; c < s.channels; ++c) out[(y * s.width + x) * s.channels + c] = im.at(x, y, std::min(c, im.channels() - 1)) * t.scale();
  }
  void write(const float* in, const ParameterSlot& s, const ParameterTables&, Scene& scene, bool, SceneChanges&) const override {
    Material& m = scene.materials[size_t(s.material)];
    Texture& t = mutableTexture(m);
    if (t.isConstant()) {
      t.setConstant(s.channels == 3 ? Rgb(in[0], in[1], in[2]) : Rgb(in[0]));
      return;
    }
    Image& im = *t.mutableImage();
    const float inv = 1.f / t.scale();
    for (int y = 0; y < s.height; ++y)
      for (int x = 0; x < s.width; ++x)
        for (int c = 0; c < im.channels(); ++c) im.at(x, y, c) = in[(y * s.width + x) * s.channels + std::min(c, s.channels - 1)] * inv;
  }
  void offer(const Scene& scene, std::vector<OfferedName>& out) const override {
    for (size_t i = 0; i < scene.materials.size(); ++i) {
      const Material& m = scene.materials[i];
      std::vector<std::string> ids = m.aliases, mitsuba;
      ids.insert(ids.begin(), m.name);
      const std::string p = mitsubaNames()[0];  // reflectance (diffuse_reflectance is a plastic's), alpha
      for (const auto& id : ids) {
        mitsuba.push_back(id + "." + p + ".value");
        if (p != "alpha") mitsuba.push_back(id + "." + p + ".data");
      }
      out.push_back({"materials/" + m.name + "/" + property(), mitsuba, int(i)});
    }
  }
  std::string fromMitsuba(const Scene& scene, const std::vector<std::string>& owner, const std::string& prop, bool) const override {
    const auto names = mitsubaNames();
    if (std::find(names.begin(), names.end(), prop) == names.end()) return "";
    auto fail = [&](const std::string& why) -> std::string { throw InputError("parameter '" + dotted(owner, prop) + "' (a Mitsuba name): " + why); };
    // <bsdf id> or <shape id>.bsdf (a bsdf nested in a shape), each optionally through a twosided
    // wrapper's child (.brdf_0).
    std::string material;
    size_t k = 1;
    if (const int shape = owner.size() >= 2 && owner[1] == "bsdf" ? meshIndex(scene, owner[0]) : -1; shape >= 0) {
      material = scene.materials[size_t(scene.meshMaterial[size_t(shape)])].name;
      k = 2;
    } else {
      const int mi = materialIndex(scene, owner[0]);
      if (mi < 0) return fail("no material (bsdf) with id '" + owner[0] + "'");
      material = scene.materials[size_t(mi)].name;
    }
    if (k < owner.size() && owner[k] == "brdf_0") ++k;
    if (k != owner.size()) return fail("no bsdf property at '" + dotted(owner, prop) + "'");
    return "materials/" + material + "/" + property();
  }
  bool zeroBiasesReuse() const override { return true; }

 protected:
  virtual bool has(const Material& m) const = 0;
  virtual std::string which() const = 0;
  virtual void defaults(ParameterSlot& slot) const = 0;
  virtual const Texture& texture(const Material& m) const = 0;
  virtual Texture& mutableTexture(Material& m) const = 0;
  virtual std::vector<int>& table(ParameterTables& t) const = 0;
  virtual const std::vector<int>& table(const ParameterTables& t) const = 0;
  virtual std::vector<std::string> mitsubaNames() const = 0;
  static std::string dotted(const std::vector<std::string>& owner, const std::string& prop) {
    std::string s;
    for (const auto& o : owner) s += o + ".";
    return s + prop;
  }
};

class AlbedoKind final : public MaterialTextureKind {
 public:
  const char* name() const override { return "albedo"; }
  std::string property() const override { return "albedo"; }
  std::string mitsubaProperties() const override { return "reflectance, diffuse_reflectance and alpha of a bsdf"; }

 protected:
  bool has(const Material& m) const override { return m.hasAlbedo(); }
  std::string which() const override { return "diffuse and rough_plastic"; }
  void defaults(ParameterSlot& s) const override {
    s.channels = 3;
    s.lower = kPositiveFloor;
    s.upper = 1.f;
  }
  const Texture& texture(const Material& m) const override { return m.albedo; }
  Texture& mutableTexture(Material& m) const override { return m.albedo; }
  std::vector<int>& table(ParameterTables& t) const override { return t.albedo; }
  const std::vector<int>& table(const ParameterTables& t) const override { return t.albedo; }
  std::vector<std::string> mitsubaNames() const override { return {"reflectance", "diffuse_reflectance"}; }
};

class RoughnessKind final : public MaterialTextureKind {
 public:
  const char* name() const override { return "roughness"; }
  std::string property() const override { return "roughness"; }
  std::string mitsubaProperties() const override { return "reflectance, diffuse_reflectance and alpha of a bsdf"; }
  bool zeroBiasesReuse() const override { return false; }

 protected:
  bool has(const Material& m) const override { return m.hasRoughness(); }
  std::string which() const override { return "rough_conductor and rough_plastic"; }
  void defaults(ParameterSlot& s) const override {
    s.channels = 1;
    s.lower = 0.01f;
    s.upper = 1.f;
  }
  const Texture& texture(const Material& m) const override { return m.roughness; }
  Texture& mutableTexture(Material& m) const override { return m.roughness; }
  std::vector<int>& table(ParameterTables& t) const override { return t.roughness; }
  const std::vector<int>& table(const ParameterTables& t) const override { return t.roughness; }
  std::vector<std::string> mitsubaNames() const override { return {"alpha"}; }
};

const RegisterParameterKind kAlbedo(10, std::make_unique<AlbedoKind>());
const RegisterParameterKind kRoughness(11, std::make_unique<RoughnessKind>());

}  // namespace

}  // namespace invr
