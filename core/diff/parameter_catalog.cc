#include "core/diff/parameter_catalog.h"

#include <algorithm>

#include "core/diff/parameter_kind.h"
#include "core/error.h"

namespace invr {

namespace {

// The Mitsuba names that resolve to `name` in this scene (checked through the same mapping a job's
// names go through, so none is listed that would not be accepted).
std::vector<std::string> aliasesOf(const Scene& scene, const std::string& name, const std::vector<std::string>& candidates) {
  std::vector<std::string> out;
  for (const auto& c : candidates) {
    try {
      if (invrParameterName(scene, c) == name && std::find(out.begin(), out.end(), c) == out.end()) out.push_back(c);
    } catch (const InputError&) {
    }
  }
  return out;
}

}  // namespace

std::vector<ParameterInfo> optimisableParameters(const Scene& scene) {
  // Every kind's names, grouped as a scene lists its objects: by kind group, then object, then kind.
  struct Offer {
    int order, group;  // the kind's place; the first kind's place with the same first name part
    OfferedName name;
  };
  std::vector<Offer> offers;
  std::vector<std::string> firsts;  // first name parts, in order of their first kind
  int order = 0;
  for (const ParameterKind* k : parameterKinds()) {
    std::vector<OfferedName> names;
    k->offer(scene, names);
    for (auto& n : names) {
      const std::string first = n.name.substr(0, n.name.find('/'));
      auto it = std::find(firsts.begin(), firsts.end(), first);
      if (it == firsts.end()) it = firsts.insert(firsts.end(), first);
      offers.push_back({order, int(it - firsts.begin()), std::move(n)});
    }
    ++order;
  }
  // Kinds sharing a first name part list together, object by object (a material's albedo, then
  // its roughness); groups of shapes come after the shapes (their objects are numbered after).
  std::stable_sort(offers.begin(), offers.end(), [](const Offer& a, const Offer& b) {
    if (a.group != b.group) return a.group < b.group;
    if (a.name.object != b.name.object) return a.name.object < b.name.object;
    return a.order < b.order;
  });

  std::vector<ParameterInfo> out;
  for (const Offer& o : offers) {
    const OfferedName& offered = o.name;
    ParameterRegistry reg;  // one per name: each is asked about on its own
    try {
      const ParameterSlot& s = reg.add(scene, offered.name);
      ParameterInfo info;
      info.name = offered.name;
      info.kind = s.kind->name();
      info.size = s.size;
      info.width = s.width;
      info.height = s.height;
      info.channels = s.kind->catalogChannels(s);
      info.lower = s.lower;
      info.upper = s.upper;
      info.learningRate = s.learningRate;
      // A texture is Mitsuba's bitmap (.data), a constant its .value.
      std::vector<std::string> forms;
      for (const auto& m : offered.mitsuba) {
        const bool data = m.size() > 5 && m.compare(m.size() - 5, 5, ".data") == 0;
        if (m.size() <= 6 || m.compare(m.size() - 6, 6, ".value") != 0 ? (!data || s.width > 0) : s.width == 0) forms.push_back(m);
      }
      info.aliases = aliasesOf(scene, offered.name, forms);
      out.push_back(std::move(info));
    } catch (const InputError&) {
      // not optimisable in this scene (no roughness, a single light, ...)
    }
  }
  return out;
}

}  // namespace invr
