// A kind of optimisation parameter: how its names look and bind to a scene, how its values are
// read from and written to the scene, what `invr params` lists of it (with its Mitsuba names), and
// what the rest of invr needs to know about it (whether it has a truth, how results hold it).
// Each kind is one file that registers itself:
//
//   param_material.cc              materials/<m>/albedo, materials/<m>/roughness
//   param_light.cc                 lights/<l>/intensity
//   param_environment_texels.cc    lights/<l>/texels (an image environment map)
//   param_pose.cc                  shapes|groups/<s>/translation, rotation, scale (or one component)
//   param_vertices.cc              shapes/<s>/vertices
//   param_sampling.cc              sampling/light_logits, sampling/pixel_light_logits/<v>,
//                                  sampling/rr_survival
//   param_camera.cc                cameras/<v>/translation, rotation (or one component)
//
// Dispatch happens at bind time: a kind fills the registry's dense tables (ParameterTables), which
// the estimators read while rendering. docs/architecture.md shows how to add one.
#pragma once

#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "core/diff/parameters.h"

namespace invr {

// A parameter's name as given and, once Mitsuba names are translated, split at '/'.
struct ParameterName {
  std::string given;
  std::vector<std::string> parts;
};

// What writing values changed, applied once after every kind wrote (light selection follows
// emission; logits are selection itself).
struct SceneChanges {
  bool emission = false, selection = false;
};

// One name `invr params` offers: the invr name, the Mitsuba names that may mean it (each checked
// through invrParameterName before it is listed), and where it sorts (by `object` within its
// kind's group, then by kind).
struct OfferedName {
  std::string name;
  std::vector<std::string> mitsuba;
  int object = 0;
};

class ParameterKind {
 public:
  virtual ~ParameterKind() = default;
  // Its name in catalogs (ParameterInfo::kind), e.g. "albedo", "light_intensity".
  virtual const char* name() const = 0;
  // The first part of its names ("materials", "lights", "shapes", "groups", "sampling", "cameras").
  virtual std::vector<std::string> groups() const = 0;
  // Its property: the name part that selects it within its group ("albedo"; a sampling kind's
  // second part, "light_logits").
  virtual std::string property() const = 0;
  // How its names are written, for messages ("materials/<name>/albedo").
  virtual std::string usage() const = 0;
  // Whether `parts` names this kind (group and property match; the rest may still be wrong).
  virtual bool claims(const std::vector<std::string>& parts) const;

  // The slot of a name this kind claims: kind, owners, size, channels, texture size, default
  // bounds and learning rate (offset and options are the registry's). Throws InputError saying
  // what is wrong (no such object, not of the right type, the same value as an earlier slot).
  virtual ParameterSlot bind(const Scene& scene, const ParameterName& name, const ParameterOptions& options,
                             const ParameterTables& tables, const std::vector<ParameterSlot>& earlier) const = 0;
  // Records the bound slot (its offset and options applied) in the tables; may still refuse the
  // options (a scale's lower bound must be positive).
  virtual void attach(const Scene& scene, const ParameterSlot& slot, ParameterTables& tables) const = 0;
  virtual void read(const Scene& scene, const ParameterSlot& slot, const ParameterTables& tables, float* out) const = 0;
  virtual void write(const float* in, const ParameterSlot& slot, const ParameterTables& tables, Scene& scene, bool refreshSampling,
                     SceneChanges& changes) const = 0;

  // The names of this kind in `scene` worth asking the registry about (the catalog keeps those
  // that bind).
  virtual void offer(const Scene& scene, std::vector<OfferedName>& out) const = 0;
  // A Mitsuba 3 key (mi.traverse) in this kind's terms: `owner` its object path, `property` the
  // last part before .value or .data (`data`: it ended in .data). The invr name, "" if not this
  // kind's; throws InputError when it is this kind's property but names nothing.
  virtual std::string fromMitsuba(const Scene& scene, const std::vector<std::string>& owner, const std::string& property, bool data) const;
  // For the message listing what Mitsuba properties have an invr parameter ("" for none).
  virtual std::string mitsubaProperties() const { return ""; }
  // Values per element in the catalog (a pose's components are listed as 3 per vector).
  virtual int catalogChannels(const ParameterSlot& slot) const;

  // Sampling parameters: they change a render's noise, never its mean, so they have no truth and
  // jobs (not scenes) carry their values.
  virtual bool changesNoiseOnly() const { return false; }
  // Values relative to the scene's geometry (poses, vertices): an exported scene holds them baked in.
  virtual bool relativeToGeometry() const { return false; }
  // Whether a value at 0 would bias ReSTIR's reuse (its lower bound must then be above 0).
  virtual bool zeroBiasesReuse() const { return false; }
  // Whether variance-aware losses have its derivatives.
  virtual bool varianceDerivatives() const { return true; }
  // A mesh (results hold it as a PLY; its start is another mesh, not a value).
  virtual bool isMesh() const { return false; }
};

// Registers a kind; a file defines one at namespace scope. `order` sorts kinds (and the catalog):
// materials 10s, lights 20s, shapes 30s, sampling 40s, cameras 50s. Throws std::logic_error for a name already
// registered.
struct RegisterParameterKind {
  RegisterParameterKind(int order, std::unique_ptr<ParameterKind> kind);
};

// Every registered kind, in order.
const std::vector<const ParameterKind*>& parameterKinds();

// Helpers the kinds share (parameters.cc).
int materialIndex(const Scene& scene, const std::string& name);  // by name or alias; -1 if none
int lightIndex(const Scene& scene, const std::string& name);
int meshIndex(const Scene& scene, const std::string& name);
// "; did you mean 'red'?" among `names`.
std::string closestName(const std::string& given, const std::vector<std::string>& names);
[[noreturn]] void failParameter(const std::string& given, const std::string& why);
// The light a name's second part names; throws naming the closest light when there is none.
int namedLight(const Scene& scene, const ParameterName& name);
// Throws "the same value as parameter ..., listed twice" when `offset` (a table's entry for the
// object, -1 if none) is an earlier slot's.
void refuseSameValue(const ParameterName& name, int offset, const std::vector<ParameterSlot>& earlier);
// A pose kind's vector in a rigid motion: its translation (firstField 0) or its rotation in
// degrees (3), read whole, or written whole (component -1) or one component.
Vec3 motionVector(const RigidMotion& m, int firstField);
void setMotionVector(RigidMotion& m, int firstField, const float* in, int component);

}  // namespace invr
