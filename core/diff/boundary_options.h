// A boundary term's own options (optimization.boundary.terms.<name>): a type of the term's own,
// parsed by the term from its message and held in BoundaryOptions under the term's registered
// name, so no central struct holds another term's fields.
#pragma once

#include <map>
#include <memory>
#include <string>
#include <utility>

#include "core/error.h"

namespace invr {

struct BoundaryTermOptions {
  virtual ~BoundaryTermOptions() = default;
  virtual std::unique_ptr<BoundaryTermOptions> clone() const { return std::make_unique<BoundaryTermOptions>(*this); }
  bool enabled = true;  // false: the term is left out (an ablation)
  int samples = 0;      // edge samples per view and step; 0: the boundary's (BoundaryOptions::samples)
};

// A term's options type T derives from BoundaryTermOptionsOf<T> and names its term in
// `static constexpr const char* kTerm`.
template <class T>
struct BoundaryTermOptionsOf : BoundaryTermOptions {
  std::unique_ptr<BoundaryTermOptions> clone() const override { return std::make_unique<T>(static_cast<const T&>(*this)); }
};

// Per term name, the options a job set; copies are deep, so a copied GradientOptions can be changed
// alone (tests and ablations do).
class BoundaryTermOptionSlots {
 public:
  BoundaryTermOptionSlots() = default;
  BoundaryTermOptionSlots(const BoundaryTermOptionSlots& o) { *this = o; }
  BoundaryTermOptionSlots& operator=(const BoundaryTermOptionSlots& o) {
    if (this != &o) {
      slots_.clear();
      for (const auto& [name, opts] : o.slots_) slots_.emplace(name, opts->clone());
    }
    return *this;
  }
  BoundaryTermOptionSlots(BoundaryTermOptionSlots&&) = default;
  BoundaryTermOptionSlots& operator=(BoundaryTermOptionSlots&&) = default;

  void set(const std::string& term, std::unique_ptr<BoundaryTermOptions> options) { slots_[term] = std::move(options); }
  // The term's options, or nullptr when the job set none (the term's defaults apply).
  const BoundaryTermOptions* find(const std::string& term) const {
    auto it = slots_.find(term);
    return it == slots_.end() ? nullptr : it->second.get();
  }
  // T's options, made with T's defaults on first use.
  template <class T>
  T& get() {
    std::unique_ptr<BoundaryTermOptions>& slot = slots_[T::kTerm];
    if (!slot) slot = std::make_unique<T>();
    T* t = dynamic_cast<T*>(slot.get());
    INVR_INVARIANT(t != nullptr, "a boundary term's options are of its own type");
    return *t;
  }
  // T's options as set, or T's defaults.
  template <class T>
  const T& getOr() const {
    static const T defaults;
    const BoundaryTermOptions* o = find(T::kTerm);
    if (!o) return defaults;
    const T* t = dynamic_cast<const T*>(o);
    INVR_INVARIANT(t != nullptr, "a boundary term's options are of its own type");
    return *t;
  }

 private:
  std::map<std::string, std::unique_ptr<BoundaryTermOptions>> slots_;
};

}  // namespace invr
