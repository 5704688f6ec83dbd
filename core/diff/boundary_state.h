// What a boundary term keeps between gradient steps (edge reservoirs, ...): a type of the term's
// own, held in the slot the engine's session keeps for the term under its registered name
// (EngineSession::boundary), so a term needs nothing of the engine.
#pragma once

#include <map>
#include <memory>
#include <string>

namespace invr {

struct BoundaryTermState {
  virtual ~BoundaryTermState() = default;
};

// One slot per term name; empty until the term first keeps something.
using BoundaryStateSlots = std::map<std::string, std::unique_ptr<BoundaryTermState>>;

// The state of type T in `slot`, made on first use.
template <class T>
T& boundaryState(std::unique_ptr<BoundaryTermState>& slot) {
  if (!slot) slot = std::make_unique<T>();
  return static_cast<T&>(*slot);
}

}  // namespace invr
