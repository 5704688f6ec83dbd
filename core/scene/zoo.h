// The scene zoo (../shared/DESIGN.md): procedural scenes built in code, usable by name.
#pragma once

#include <string>
#include <vector>

#include "invr/v1/scene.pb.h"

namespace invr {

struct ZooEntry {
  std::string name;
  std::string description;
};

const std::vector<ZooEntry>& zooEntries();
// Throws InputError listing the known names when `name` is unknown.
invr::v1::Scene zooScene(const std::string& name);

}  // namespace invr
