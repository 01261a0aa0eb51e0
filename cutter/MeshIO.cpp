#include "cutter/MeshIO.h"

#include "cutter/MeshCheck.h"
#include "vdb/AtomicFile.h"
#include "vdb/Error.h"

// OpenMesh's PropertyT::push_back() appends a default (uninitialised) VectorT,
// which GCC 12 flags in this file's instantiations; the value is overwritten.
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#include <OpenMesh/Core/IO/MeshIO.hh>
#include <OpenMesh/Core/Mesh/TriMesh_ArrayKernelT.hh>
#include <OpenMesh/Core/System/omstream.hh>

#include <algorithm>
#include <cctype>
#include <cstdio>
#include <filesystem>
#include <cmath>
#include <tuple>

#include <tbb/parallel_sort.h>

namespace mtcut::cutter {

namespace {

struct Traits : OpenMesh::DefaultTraits
{
    using Point = OpenMesh::Vec3f;
    using Normal = OpenMesh::Vec3f;
};
using OMesh = OpenMesh::TriMesh_ArrayKernelT<Traits>;

std::string lowerExtension(const std::string& path)
{
    std::string ext = std::filesystem::path(path).extension().string();
    std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return char(std::tolower(c)); });
    return ext;
}

/// OpenMesh refuses faces that would make its half-edge structure
/// non-manifold; such a face gets its own copies of the vertices, so the
/// file still holds every triangle.
void toOpenMesh(const Mesh& mesh, OMesh& om)
{
    const bool normals = !mesh.normals.empty() && mesh.normals.size() == mesh.positions.size();
    if (normals) om.request_vertex_normals();
    om.reserve(mesh.positions.size(), mesh.indices.size(), mesh.triangleCount());
    std::vector<OMesh::VertexHandle> vh(mesh.positions.size());
    auto addVertex = [&](uint32_t v) {
        const glm::vec3& p = mesh.positions[v];
        const OMesh::VertexHandle h = om.add_vertex(OMesh::Point(p.x, p.y, p.z));
        if (normals) om.set_normal(h, OMesh::Normal(mesh.normals[v].x, mesh.normals[v].y, mesh.normals[v].z));
        return h;
    };
    for (size_t v = 0; v < mesh.positions.size(); ++v) vh[v] = addVertex(uint32_t(v));
    for (size_t t = 0; t < mesh.triangleCount(); ++t) {
        const uint32_t a = mesh.indices[3 * t], b = mesh.indices[3 * t + 1], c = mesh.indices[3 * t + 2];
        if (a >= vh.size() || b >= vh.size() || c >= vh.size()) throw InputError("mesh has an index out of range");
        if (!om.add_face(vh[a], vh[b], vh[c]).is_valid()) om.add_face(addVertex(a), addVertex(b), addVertex(c));
    }
}

} // namespace

bool hasMeshExtension(const std::string& path)
{
    const std::string ext = lowerExtension(path);
    return ext == ".stl" || ext == ".obj" || ext == ".ply" || ext == ".off";
}

MeshFormat meshFormatFromPath(const std::string& path)
{
    const std::string ext = lowerExtension(path);
    if (ext == ".stl") return MeshFormat::Stl;
    if (ext == ".obj") return MeshFormat::Obj;
    if (ext == ".ply") return MeshFormat::Ply;
    if (ext == ".off") return MeshFormat::Off;
    throw InputError(path + ": unknown mesh format '" + ext + "' (expected .stl, .obj, .ply or .off)");
}

void writeMesh(const Mesh& mesh, const std::string& path)
{
    const MeshFormat format = meshFormatFromPath(path);
    OMesh om;
    toOpenMesh(mesh, om);
    OpenMesh::IO::Options options;
    if (format == MeshFormat::Stl || format == MeshFormat::Ply) options += OpenMesh::IO::Options::Binary;
    if (format == MeshFormat::Stl) {
        om.request_face_normals();
        om.update_face_normals();
        options += OpenMesh::IO::Options::FaceNormal;
    }
    if ((format == MeshFormat::Obj || format == MeshFormat::Ply) && om.has_vertex_normals()) {
        options += OpenMesh::IO::Options::VertexNormal;
    }
    omout().disable(); // OpenMesh's writers chat on stdout ("[STLWriter] : write binary file")
    omlog().disable();
    writeFileAtomically(path, [&](const std::string& tmp) {
        // OpenMesh picks the writer from the extension: keep it on the temporary name.
        const std::string named = tmp + lowerExtension(path);
        const bool ok = OpenMesh::IO::write_mesh(om, named, options);
        std::error_code ec;
        if (ok) std::filesystem::rename(named, tmp, ec);
        if (!ok || ec) {
            std::filesystem::remove(named, ec);
            throw InputError(path + ": cannot write the mesh");
        }
    });
}

std::vector<std::string> writeShells(const Mesh& mesh, const std::string& path)
{
    const std::filesystem::path p(path);
    const std::vector<Mesh> shells = splitShells(mesh);
    std::vector<std::string> paths;
    for (size_t i = 0; i < shells.size(); ++i) {
        char suffix[32];
        std::snprintf(suffix, sizeof suffix, "_shell%03zu", i + 1);
        const std::string out = (p.parent_path() / (p.stem().string() + suffix + p.extension().string())).string();
        writeMesh(shells[i], out);
        paths.push_back(out);
    }
    return paths;
}

size_t coincidentVertices(const Mesh& mesh)
{
    std::vector<uint32_t> order; // the finite ones (a NaN would break the sort's order)
    order.reserve(mesh.positions.size());
    for (uint32_t v = 0; v < uint32_t(mesh.positions.size()); ++v) {
        const glm::vec3& p = mesh.positions[v];
        if (std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z)) order.push_back(v);
    }
    auto key = [&](uint32_t v) {
        const glm::vec3& p = mesh.positions[v];
        return std::make_tuple(p.x, p.y, p.z);
    };
    tbb::parallel_sort(order.begin(), order.end(), [&](uint32_t a, uint32_t b) { return key(a) < key(b); });
    size_t count = 0;
    for (size_t i = 0; i < order.size();) {
        size_t j = i + 1;
        while (j < order.size() && key(order[j]) == key(order[i])) ++j;
        if (j - i > 1) count += j - i;
        i = j;
    }
    return count;
}

Mesh readMesh(const std::string& path)
{
    (void)meshFormatFromPath(path);
    if (!std::filesystem::exists(path)) throw InputError(path + ": no such file");
    OMesh om;
    om.request_vertex_normals();
    OpenMesh::IO::Options options;
    options += OpenMesh::IO::Options::VertexNormal;
    // The reader gives a face it cannot add to a manifold mesh its own copies
    // of the vertices and says so on stderr, once a face ("complex edge",
    // thousands for a damaged file); checkMesh reports such faces (open
    // edges), so the reader is kept quiet.
    omerr().disable();
    const bool read = OpenMesh::IO::read_mesh(om, path, options);
    omerr().enable();
    if (!read) throw InputError(path + ": cannot read the mesh");
    Mesh mesh;
    mesh.positions.reserve(om.n_vertices());
    for (const auto v : om.vertices()) {
        const auto p = om.point(v);
        mesh.positions.emplace_back(p[0], p[1], p[2]);
    }
    if (options.check(OpenMesh::IO::Options::VertexNormal)) {
        for (const auto v : om.vertices()) {
            const auto n = om.normal(v);
            mesh.normals.emplace_back(n[0], n[1], n[2]);
        }
    }
    for (const auto f : om.faces()) {
        std::vector<uint32_t> poly;
        for (const auto v : om.fv_range(f)) poly.push_back(uint32_t(v.idx()));
        for (size_t k = 1; k + 1 < poly.size(); ++k) {
            mesh.indices.insert(mesh.indices.end(), {poly[0], poly[k], poly[k + 1]});
        }
    }
    return mesh;
}

} // namespace mtcut::cutter
