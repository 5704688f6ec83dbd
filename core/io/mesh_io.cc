#include "core/io/mesh_io.h"

#include <tiny_obj_loader.h>

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <map>
#include <sstream>
#include <unordered_map>

#include "core/error.h"
#include "core/limits.h"

namespace invr {

namespace {

// Reads a string in place: an istringstream would copy a mesh file of up to a gibibyte.
class MemoryStreamBuf : public std::streambuf {
 public:
  explicit MemoryStreamBuf(const std::string& s) {
    char* p = const_cast<char*>(s.data());  // only ever read
    setg(p, p, p + s.size());
  }

 protected:
  pos_type seekoff(off_type off, std::ios_base::seekdir dir, std::ios_base::openmode which) override {
    if (which & std::ios_base::out) return pos_type(off_type(-1));
    char* base = dir == std::ios_base::beg ? eback() : dir == std::ios_base::cur ? gptr() : egptr();
    if (off < eback() - base || off > egptr() - base) return pos_type(off_type(-1));
    setg(eback(), base + off, egptr());
    return pos_type(gptr() - eback());
  }
  pos_type seekpos(pos_type pos, std::ios_base::openmode which) override { return seekoff(off_type(pos), std::ios_base::beg, which); }
};

// tinyobjloader reads "nan" as 0 and "1e999" as infinity without a word: every number of a
// v/vn/vt line is checked here first, with its line number.
void checkObjNumbers(const std::string& bytes, const std::string& name) {
  size_t line = 0;
  for (size_t pos = 0; pos < bytes.size();) {
    size_t end = bytes.find_first_of("\n\r", pos);  // tinyobjloader ends a line at either
    if (end == std::string::npos) end = bytes.size();
    ++line;
    const char* p = bytes.data() + pos;
    const char* e = bytes.data() + end;
    while (p < e && (*p == ' ' || *p == '\t')) ++p;
    if (p < e && *p == 'v' && (p + 1 == e || p[1] == ' ' || p[1] == '\t' || ((p[1] == 'n' || p[1] == 't') && (p + 2 == e || p[2] == ' ' || p[2] == '\t')))) {
      p += (p + 1 < e && (p[1] == 'n' || p[1] == 't')) ? 2 : 1;
      for (;;) {
        while (p < e && (*p == ' ' || *p == '\t' || *p == '\r')) ++p;
        if (p >= e || *p == '#') break;
        const char* tokEnd = p;
        while (tokEnd < e && *tokEnd != ' ' && *tokEnd != '\t' && *tokEnd != '\r') ++tokEnd;
        std::string tok(p, size_t(tokEnd - p));
        char* stop = nullptr;
        double v = std::strtod(tok.c_str(), &stop);
        if (stop == tok.c_str() || *stop != '\0' || !std::isfinite(v) || std::abs(v) > 3.0e38)
          throw InputError("mesh '" + name + "': line " + std::to_string(line) + ": '" + tok.substr(0, 32) + "' is not a finite number");
        p = tokEnd;
      }
    }
    pos = end + 1;
  }
}

TriangleMesh parseObj(const std::string& bytes, const std::string& name) {
  auto fail = [&](const std::string& why) { throw InputError("mesh '" + name + "': " + why); };
  checkObjNumbers(bytes, name);
  tinyobj::ObjReaderConfig cfg;
  cfg.triangulate = true;
  cfg.vertex_color = false;
  tinyobj::ObjReader reader;
  // Materials are not read: an OBJ names its .mtl by path, which means nothing for an asset.
  if (!reader.ParseFromString(bytes, std::string(), cfg)) fail(reader.Error().empty() ? "cannot parse OBJ" : reader.Error());
  const auto& attrib = reader.GetAttrib();
  const InputLimits& lim = inputLimits();
  const size_t nv = attrib.vertices.size() / 3, nn = attrib.normals.size() / 3, nt = attrib.texcoords.size() / 2;
  if (nv > lim.maxMeshVertices)
    throw ResourceError("mesh '" + name + "': " + std::to_string(nv) + " vertices (limit " + std::to_string(lim.maxMeshVertices) + ")");
  TriangleMesh m;
  std::map<std::tuple<int, int, int>, uint32_t> remap;
  bool hasN = nn > 0, hasUv = nt > 0;
  size_t face = 0;
  for (const auto& shape : reader.GetShapes()) {
    if (m.indices.size() + shape.mesh.indices.size() > 3 * lim.maxMeshTriangles)
      throw ResourceError("mesh '" + name + "': more than " + std::to_string(lim.maxMeshTriangles) + " triangles");
    for (size_t k = 0; k < shape.mesh.indices.size(); ++k) {
      const auto& idx = shape.mesh.indices[k];
      if (k % 3 == 0) ++face;
      // Every index is checked against its array: tinyobjloader resolves relative indices but
      // does not range-check them.
      if (idx.vertex_index < 0 || size_t(idx.vertex_index) >= nv)
        fail("face " + std::to_string(face) + " references vertex " + std::to_string(idx.vertex_index + 1) + " of " + std::to_string(nv));
      if (hasN) {
        if (idx.normal_index < 0) fail("some faces have normals and some do not (face " + std::to_string(face) + ")");
        if (size_t(idx.normal_index) >= nn)
          fail("face " + std::to_string(face) + " references normal " + std::to_string(idx.normal_index + 1) + " of " + std::to_string(nn));
      }
      if (hasUv && idx.texcoord_index >= 0 && size_t(idx.texcoord_index) >= nt)
        fail("face " + std::to_string(face) + " references texture coordinate " + std::to_string(idx.texcoord_index + 1) + " of " +
             std::to_string(nt));
      auto key = std::make_tuple(idx.vertex_index, hasN ? idx.normal_index : -1, hasUv ? idx.texcoord_index : -1);
      auto [it, inserted] = remap.try_emplace(key, uint32_t(m.positions.size()));
      if (inserted) {
        const float* v = &attrib.vertices[3 * size_t(idx.vertex_index)];
        m.positions.push_back({v[0], v[1], v[2]});
        if (hasN) {
          const float* n = &attrib.normals[3 * size_t(idx.normal_index)];
          Vec3 nv3(n[0], n[1], n[2]);
          if (!isFinite(nv3)) fail("normal " + std::to_string(idx.normal_index + 1) + " is not finite");
          m.normals.push_back(lengthSquared(nv3) > 0.f ? normalize(nv3) : Vec3(0.f, 0.f, 1.f));
        }
        if (hasUv) {
          Vec2 uv(0.f, 0.f);
          if (idx.texcoord_index >= 0) uv = {attrib.texcoords[2 * size_t(idx.texcoord_index)], attrib.texcoords[2 * size_t(idx.texcoord_index) + 1]};
          m.uvs.push_back(uv);
        }
      }
      m.indices.push_back(it->second);
    }
  }
  return m;
}

// PLY reader: vertex (x y z [nx ny nz] [u v | s t]) and face (vertex_indices list); other
// elements are read and skipped. Counts the header declares are checked against the limits and
// against the bytes the file holds before anything is reserved for them.
TriangleMesh parsePly(const std::string& bytes, const std::string& name) {
  MemoryStreamBuf buffer(bytes);
  std::istream in(&buffer);
  auto fail = [&](const std::string& why) -> TriangleMesh { throw InputError("mesh '" + name + "': " + why); };
  const InputLimits& lim = inputLimits();
  std::string line;
  if (!std::getline(in, line) || line.rfind("ply", 0) != 0) return fail("not a PLY file (missing 'ply' magic)");
  enum class Fmt { Ascii, BinLE, BinBE } fmt = Fmt::Ascii;
  bool haveFormat = false;
  struct Prop { std::string name, type, countType; bool list = false; };
  struct Element { std::string name; uint64_t count = 0; std::vector<Prop> props; };
  std::vector<Element> elements;
  auto typeSize = [&](const std::string& t) -> size_t {
    if (t == "char" || t == "uchar" || t == "int8" || t == "uint8") return 1;
    if (t == "short" || t == "ushort" || t == "int16" || t == "uint16") return 2;
    if (t == "int" || t == "uint" || t == "int32" || t == "uint32" || t == "float" || t == "float32") return 4;
    if (t == "double" || t == "float64") return 8;
    fail("unknown property type '" + t + "'");
    return 0;
  };
  auto isIntegerType = [](const std::string& t) { return t != "float" && t != "float32" && t != "double" && t != "float64"; };
  bool ended = false;
  int headerLine = 1;
  while (std::getline(in, line)) {
    ++headerLine;
    if (headerLine > 10000) return fail("header longer than 10000 lines");
    if (!line.empty() && line.back() == '\r') line.pop_back();
    std::istringstream ss(line);
    std::string kw;
    ss >> kw;
    const std::string at = " (header line " + std::to_string(headerLine) + ")";
    if (kw == "format") {
      std::string f, version;
      ss >> f >> version;
      if (f == "ascii") fmt = Fmt::Ascii;
      else if (f == "binary_little_endian") fmt = Fmt::BinLE;
      else if (f == "binary_big_endian") fmt = Fmt::BinBE;
      else return fail("unknown PLY format '" + f + "'" + at);
      haveFormat = true;
    } else if (kw == "element") {
      Element e;
      std::string count;
      ss >> e.name >> count;
      if (e.name.empty() || count.empty() || count.size() > 12 || !std::all_of(count.begin(), count.end(), ::isdigit))
        return fail("element '" + e.name + "': count '" + count + "' is not a non-negative integer" + at);
      e.count = std::stoull(count);
      uint64_t limit = e.name == "face" ? lim.maxMeshTriangles : lim.maxMeshVertices;
      if (e.count > limit)
        throw ResourceError("mesh '" + name + "': element '" + e.name + "' declares " + count + " entries (limit " + std::to_string(limit) + ")");
      elements.push_back(e);
    } else if (kw == "property") {
      if (elements.empty()) return fail("property before any element" + at);
      Prop p;
      std::string t;
      ss >> t;
      if (t == "list") {
        p.list = true;
        ss >> p.countType >> p.type >> p.name;
        typeSize(p.countType);
        if (!isIntegerType(p.countType)) return fail("list count type '" + p.countType + "' is not an integer type" + at);
      } else {
        p.type = t;
        ss >> p.name;
      }
      typeSize(p.type);
      if (p.name.empty()) return fail("property without a name" + at);
      elements.back().props.push_back(p);
    } else if (kw == "end_header") {
      ended = true;
      break;
    } else if (kw != "comment" && kw != "obj_info" && !kw.empty()) {
      return fail("unknown header keyword '" + kw + "'" + at);
    }
  }
  if (!ended) return fail("truncated header (no end_header)");
  if (!haveFormat) return fail("header has no 'format' line");
  // Each entry takes at least this many bytes (an ASCII value at least two characters), so a
  // count the file cannot hold is an error before anything is reserved for it.
  uint64_t remaining = uint64_t(bytes.size()) - uint64_t(std::max<std::streamoff>(0, in.tellg()));
  for (const auto& e : elements) {
    if (e.count == 0) continue;
    if (e.props.empty()) return fail("element '" + e.name + "' has entries but no properties");
    uint64_t minBytes = 0;
    for (const auto& pr : e.props) minBytes += fmt == Fmt::Ascii ? 2 : typeSize(pr.list ? pr.countType : pr.type);
    if (e.count > remaining / minBytes)
      return fail("element '" + e.name + "' declares " + std::to_string(e.count) + " entries, but the file holds at most " +
                  std::to_string(remaining / minBytes) + " (truncated?)");
    remaining -= e.count * minBytes;  // the elements follow one another
  }
  auto readValue = [&](const std::string& t, const char* what, uint64_t i) -> double {
    if (fmt == Fmt::Ascii) {
      std::string tok;
      if (!(in >> tok)) fail("truncated data in " + std::string(what) + " " + std::to_string(i));
      char* end = nullptr;
      double v = std::strtod(tok.c_str(), &end);
      if (end == tok.c_str() || *end != '\0') fail("malformed number '" + tok.substr(0, 32) + "' in " + what + " " + std::to_string(i));
      return v;
    }
    size_t n = typeSize(t);
    unsigned char b[8];
    if (!in.read(reinterpret_cast<char*>(b), std::streamsize(n))) fail("truncated data in " + std::string(what) + " " + std::to_string(i));
    if ((fmt == Fmt::BinBE) == (std::endian::native == std::endian::little)) std::reverse(b, b + n);
    auto as = [&](auto v) { std::memcpy(&v, b, sizeof v); return double(v); };
    if (t == "char" || t == "int8") return as(int8_t());
    if (t == "uchar" || t == "uint8") return as(uint8_t());
    if (t == "short" || t == "int16") return as(int16_t());
    if (t == "ushort" || t == "uint16") return as(uint16_t());
    if (t == "int" || t == "int32") return as(int32_t());
    if (t == "uint" || t == "uint32") return as(uint32_t());
    if (t == "float" || t == "float32") return as(float());
    return as(double());
  };
  // An index or count: integral, non-negative, below `bound`.
  auto integer = [&](double v, double bound, const std::string& what) -> uint32_t {
    if (!(v >= 0.0) || v != std::floor(v) || v >= bound) {
      char b[40];
      std::snprintf(b, sizeof b, "%.10g", v);
      fail(what + " is " + b + " (must be an integer in 0.." + std::to_string(uint64_t(bound) - 1) + ")");
    }
    return uint32_t(v);
  };
  TriangleMesh m;
  uint64_t vertexCount = 0, faceCount = 0;
  for (const auto& e : elements) {
    if (e.name == "vertex") vertexCount += e.count;
    if (e.name == "face") faceCount += e.count;
  }
  if (faceCount > 0 && vertexCount == 0) return fail("faces but no vertices (no 'vertex' element, or one of 0 entries)");
  if (vertexCount > lim.maxMeshVertices)
    throw ResourceError("mesh '" + name + "': " + std::to_string(vertexCount) + " vertices (limit " + std::to_string(lim.maxMeshVertices) + ")");
  m.positions.reserve(size_t(vertexCount));
  std::vector<uint32_t> poly;
  for (const auto& e : elements) {
    const bool isVertex = e.name == "vertex", isFace = e.name == "face";
    const char* what = isVertex ? "vertex" : isFace ? "face" : "element";
    for (uint64_t i = 0; i < e.count; ++i) {
      Vec3 p(0.f), n(0.f);
      Vec2 uv(0.f, 0.f);
      bool hasN = false, hasUv = false;
      for (const auto& pr : e.props) {
        if (pr.list) {
          uint32_t cnt = integer(readValue(pr.countType, what, i), double(lim.maxPolygonVertices) + 1,
                                 std::string(what) + " " + std::to_string(i) + ": list length");
          poly.resize(cnt);
          const bool indices = isFace && (pr.name == "vertex_indices" || pr.name == "vertex_index");
          for (auto& v : poly) {
            double x = readValue(pr.type, what, i);
            v = indices ? integer(x, double(vertexCount), "face " + std::to_string(i) + ": vertex index") : 0u;
          }
          if (indices) {
            if (cnt < 3) fail("face " + std::to_string(i) + " has fewer than 3 vertices");
            if (m.indices.size() / 3 + (cnt - 2) > lim.maxMeshTriangles)
              throw ResourceError("mesh '" + name + "': more than " + std::to_string(lim.maxMeshTriangles) + " triangles");
            for (size_t k = 1; k + 1 < cnt; ++k) m.indices.insert(m.indices.end(), {poly[0], poly[k], poly[k + 1]});
          }
          continue;
        }
        double v = readValue(pr.type, what, i);
        if (!isVertex) continue;
        if (!std::isfinite(v)) fail("vertex " + std::to_string(i) + ": property '" + pr.name + "' is not finite");
        if (pr.name == "x") p.x = float(v); else if (pr.name == "y") p.y = float(v); else if (pr.name == "z") p.z = float(v);
        else if (pr.name == "nx") { n.x = float(v); hasN = true; } else if (pr.name == "ny") n.y = float(v); else if (pr.name == "nz") n.z = float(v);
        else if (pr.name == "u" || pr.name == "s" || pr.name == "texture_u") { uv.x = float(v); hasUv = true; }
        else if (pr.name == "v" || pr.name == "t" || pr.name == "texture_v") uv.y = float(v);
      }
      if (isVertex) {
        if (!isFinite(p)) fail("vertex " + std::to_string(i) + " is not finite (out of float range)");
        m.positions.push_back(p);
        if (hasN) m.normals.push_back(lengthSquared(n) > 0 && isFinite(n) ? normalize(n) : Vec3(0, 0, 1));
        if (hasUv) m.uvs.push_back(uv);
      }
    }
  }
  if (!m.normals.empty() && m.normals.size() != m.positions.size()) m.normals.clear();
  if (!m.uvs.empty() && m.uvs.size() != m.positions.size()) m.uvs.clear();
  return m;
}

}  // namespace

TriangleMesh parseMesh(const std::string& bytes, MeshFormat format, const std::string& name) {
  return format == MeshFormat::Ply ? parsePly(bytes, name) : parseObj(bytes, name);
}

TriangleMesh loadMesh(const std::filesystem::path& path, MemoryBudget* budget) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec)) throw InputError("mesh '" + path.string() + "': file not found");
  std::string ext = path.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), ::tolower);
  if (!ext.empty() && ext != ".obj" && ext != ".ply")
    throw InputError("mesh '" + path.string() + "': unsupported format '" + ext + "' (use .obj or .ply)");
  uint64_t size = std::filesystem::file_size(path, ec);
  if (ec) throw InputError("mesh '" + path.string() + "': cannot read (" + ec.message() + ")");
  if (size > inputLimits().maxFileBytes)
    throw ResourceError("mesh '" + path.string() + "': " + humanBytes(size) + " (limit " + humanBytes(inputLimits().maxFileBytes) + ")");
  std::ifstream in(path, std::ios::binary);
  char magic[4] = {0, 0, 0, 0};
  in.read(magic, 3);
  in.seekg(0);
  // Content-addressed assets have no extension: PLY files say so in their first line.
  MeshFormat f = ext == ".ply" || (ext.empty() && std::string(magic) == "ply") ? MeshFormat::Ply : MeshFormat::Obj;
  // Reading and parsing take a multiple of the file's size at their peak (the bytes, the parser's
  // arrays, OBJ's vertex map): charged before reading, released once the mesh stands (the caller
  // charges what it keeps).
  const uint64_t peak = size * (f == MeshFormat::Obj ? 8 : 4);
  if (budget) budget->charge(peak, "mesh '" + path.string() + "' (reading " + humanBytes(size) + ")");
  std::string bytes(size_t(size), '\0');
  if (!in.read(bytes.data(), std::streamsize(size))) throw InputError("mesh '" + path.string() + "': cannot read");
  TriangleMesh m = parseMesh(bytes, f, path.string());
  if (budget) budget->release(peak);
  return m;
}


void writePly(const std::filesystem::path& path, const TriangleMesh& mesh) {
  const bool normals = mesh.normals.size() == mesh.positions.size() && !mesh.normals.empty();
  std::string header = "ply\nformat binary_little_endian 1.0\ncomment written by invr\nelement vertex " + std::to_string(mesh.positions.size()) +
                       "\nproperty float x\nproperty float y\nproperty float z\n";
  if (normals) header += "property float nx\nproperty float ny\nproperty float nz\n";
  const bool uvs = mesh.uvs.size() == mesh.positions.size() && !mesh.uvs.empty();
  if (uvs) header += "property float u\nproperty float v\n";
  header += "element face " + std::to_string(mesh.triangleCount()) + "\nproperty list uchar uint vertex_indices\nend_header\n";
  std::string data;
  data.reserve(mesh.positions.size() * ((normals ? 24 : 12) + (uvs ? 8 : 0)) + mesh.triangleCount() * 13);
  auto put = [&](auto v) {
    static_assert(std::endian::native == std::endian::little, "PLY writer assumes a little-endian host");
    data.append(reinterpret_cast<const char*>(&v), sizeof v);
  };
  for (size_t i = 0; i < mesh.positions.size(); ++i) {
    for (int c = 0; c < 3; ++c) put(mesh.positions[i][c]);
    if (normals)
      for (int c = 0; c < 3; ++c) put(mesh.normals[i][c]);
    if (uvs) {
      put(mesh.uvs[i].x);
      put(mesh.uvs[i].y);
    }
  }
  for (size_t t = 0; t < mesh.triangleCount(); ++t) {
    put(uint8_t(3));
    for (int k = 0; k < 3; ++k) put(uint32_t(mesh.indices[3 * t + size_t(k)]));
  }
  std::ofstream out(path, std::ios::binary);
  if (!out) throw InputError("cannot write '" + path.string() + "'");
  out << header << data;
  if (!out.flush()) throw InputError("cannot write '" + path.string() + "'");
}

}  // namespace invr
