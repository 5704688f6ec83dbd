// Builds the renderer's Scene from its protobuf description, validating every field a user can
// get wrong; errors name the field path, e.g. "scene.shapes[2] (floor).material: unknown material".
#pragma once

#include <filesystem>
#include <functional>
#include <memory>

#include "core/limits.h"
#include "core/scene/scene.h"
#include "invr/v1/job.pb.h"
#include "invr/v1/scene.pb.h"

namespace invr {

struct AssetResolver {
  std::filesystem::path baseDir = ".";  // for AssetRef.path
  // For AssetRef.sha256 (the service's asset store); unset means hashes are not accepted.
  std::function<std::filesystem::path(const std::string&)> byHash;
  // Charged before each texture, mesh and target is allocated (the service's per-job limit);
  // null: only the per-file limits of inputLimits() apply.
  MemoryBudget* budget = nullptr;
  std::filesystem::path resolve(const invr::v1::AssetRef& ref, const std::string& field) const;
};

// What a scene is built for. Validate reads and checks everything (assets, limits, the memory
// budget) but builds no BVH: the client's early check, `invr plan` and the server, which never
// trace a ray, use it; workers and in-process runs build for Render, once per session.
enum class SceneUse { Render, Validate };

std::unique_ptr<Scene> buildScene(const invr::v1::Scene& spec, const AssetResolver& assets = {}, SceneUse use = SceneUse::Render);

// The start mesh of a vertex parameter (optimization.parameters[].initial_mesh, job.proto's
// MeshStart) for the shape `shape` of the job's scene, whose own geometry is `truth` (world space):
// in world space, without uvs, smooth-shaded (angle-weighted vertex normals) when `truth` has
// vertex normals and flat otherwise. Errors name `field`.
TriangleMesh startMesh(const invr::v1::MeshStart& start, const invr::v1::Shape& shape, const TriangleMesh& truth, const AssetResolver& assets,
                       const std::string& field);

// The job's scene description: its zoo entry or inline scene (Mitsuba scenes are imported by the client).
invr::v1::Scene jobSceneSpec(const invr::v1::JobSpec& job);

// The job's scene: its zoo entry or inline scene.
std::unique_ptr<Scene> buildJobScene(const invr::v1::JobSpec& job, const AssetResolver& assets = {}, SceneUse use = SceneUse::Render);

}  // namespace invr
