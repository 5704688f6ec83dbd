// Job files: the protobuf JSON mapping of invr.v1.JobSpec. Parsing is protobuf's; this adds the
// file name and line:column to its field-path errors and checks values protobuf cannot.
#pragma once

#include <filesystem>
#include <functional>
#include <string>

#include "invr/v1/job.pb.h"

namespace invr {

// Throws InputError("<file>:<line>:<col>: <field path>: <problem>").
invr::v1::JobSpec parseJobJson(const std::string& json, const std::string& sourceName = "<job>");
invr::v1::JobSpec loadJobFile(const std::filesystem::path& path);
std::string jobToJson(const invr::v1::JobSpec& job);

// Checks what protobuf's parser lets through: every enum value is a known one, every string and
// repeated field within inputLimits(), then the render settings. parseJobJson calls it; the
// server calls it on every submission. Throws InputError naming the field.
void validateJobSpec(const invr::v1::JobSpec& job);

// Checks the render settings (negative spp, absurd depths). Throws InputError naming the field.
void validateRenderSettings(const invr::v1::RenderSettings& r, const std::string& path = "render");

// Calls fn(ref, fieldPath) for every AssetRef in the job (meshes, textures, target images), with
// paths spelled like the validation errors, e.g. "scene.shapes[2].mesh".
void forEachAssetRef(invr::v1::JobSpec& job, const std::function<void(invr::v1::AssetRef&, const std::string&)>& fn);

}  // namespace invr
