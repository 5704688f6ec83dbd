// Reading triangle meshes from OBJ and PLY files (bytes a user gave: every count and index checked).
#pragma once

#include <filesystem>
#include <string>

#include "core/geometry/mesh.h"

namespace invr {

// Loads .obj (tinyobjloader) or .ply (ascii / binary little- and big-endian).
// Throws InputError naming the file on any problem: malformed or truncated data, indices out of
// range, non-finite numbers; ResourceError when a count the file declares exceeds inputLimits().
// With a budget, the peak memory of reading and parsing (a multiple of the file's size: 8x for
// OBJ, 4x for PLY) is charged before the file is read and released once the mesh is built.
class MemoryBudget;
TriangleMesh loadMesh(const std::filesystem::path& path, MemoryBudget* budget = nullptr);

// Writes a binary little-endian PLY: vertex x y z (and nx ny nz, u v when the mesh has them), face
// vertex_indices (uchar count, uint indices). Throws InputError when the file cannot be written.
void writePly(const std::filesystem::path& path, const TriangleMesh& mesh);

enum class MeshFormat { Obj, Ply };
// The same from bytes in memory; `name` is what errors call the mesh.
TriangleMesh parseMesh(const std::string& bytes, MeshFormat format, const std::string& name);

}  // namespace invr
