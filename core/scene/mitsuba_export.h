// A scene as it is now (parameters written in, shape motion applied) written out as a Mitsuba 3
// scene file: every mesh as a world-space PLY, image textures and environment maps as EXR.
// The inverse of mitsuba_import.h on what invr renders: importing the file gives back the same
// image (tests/core/optim/results_export_test.cc). docs/mitsuba-import.md, "Export".
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include "core/scene/scene.h"

namespace invr {

struct MitsubaExportOptions {
  int spp = 16;                 // <sampler sample_count>
  int maxDepth = 1;             // invr's path vertices after the camera (1: direct illumination)
  int russianRouletteDepth = 3; // invr's bounces before roulette
};

struct MitsubaExport {
  std::vector<std::filesystem::path> files;  // the XML first, then the meshes and images
  std::vector<std::string> notes;            // what Mitsuba cannot hold, said once each
  // Mitsuba's ids are one namespace: a shape, light or camera whose name another object took
  // (materials claim first, then lights, shapes, cameras) is renamed. Pairs of parameter name
  // prefixes, e.g. {"shapes/floor/", "shapes/floor_shape/"}.
  std::vector<std::pair<std::string, std::string>> renamed;
};

// Writes `xml` and, beside it, meshes/<shape>.ply and textures/<name>.exr. Throws InputError
// when a file cannot be written.
MitsubaExport exportMitsubaScene(const Scene& scene, const std::filesystem::path& xml, const MitsubaExportOptions& options = {});

}  // namespace invr
