// repairFloatFolds (cutter/FloatRepair.h): a cut cell's exact geometry can
// hold features below a float step of the world position it is written at;
// the kernel mends them before the cell leaves it. These tests build cells by
// hand so that the exact geometry is valid and its float rounding is not, and
// check what the repair keeps: the cell's boundary (the seam with the next
// cells), orientation, and the same decision in both cells of a shared face.
// The head tests (test_cut_props) check the effect on real cuts with CGAL.
#include "cutter/FloatRepair.h"
#include "cutter/RemeshKernel.h"
#include "cutter/TriangleIntersect.h"

#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <limits>
#include <map>
#include <set>
#include <stdexcept>

namespace {

using mtcut::cutter::CutCellGeometry;
using mtcut::cutter::CutVertexId;
using mtcut::cutter::gridVertexId;
using mtcut::cutter::remesh_detail::keepFaceSidesOnceWritten;
using mtcut::cutter::remesh_detail::liftOffCellFaces;
using mtcut::cutter::remesh_detail::repairFloatFolds;
using mtcut::cutter::remesh_detail::snapToGridVertices;
using glm::dvec3;
using openvdb::Coord;

/// A vertex on the grid edge from grid vertex a to b (dim 1).
CutVertexId edgeVertex(const Coord& a, const Coord& b, uint64_t plane)
{
    CutVertexId id;
    id.dim = 1;
    id.feature = {gridVertexId(a.x(), a.y(), a.z()), gridVertexId(b.x(), b.y(), b.z()), 0};
    std::sort(id.feature.begin(), id.feature.begin() + 2);
    id.planeCount = 1;
    id.planes[0] = plane;
    return id;
}

/// A vertex inside the tet face a, b, c (dim 2).
CutVertexId faceVertex(const Coord& a, const Coord& b, const Coord& c, uint64_t plane0, uint64_t plane1)
{
    CutVertexId id;
    id.dim = 2;
    id.feature = {gridVertexId(a.x(), a.y(), a.z()), gridVertexId(b.x(), b.y(), b.z()),
                  gridVertexId(c.x(), c.y(), c.z())};
    std::sort(id.feature.begin(), id.feature.end());
    id.planeCount = 2;
    id.planes[0] = plane0;
    id.planes[1] = plane1;
    return id;
}

/// A vertex inside tet `tet` of `cell` (dim 3).
CutVertexId innerVertex(const Coord& cell, uint64_t tet, uint64_t plane)
{
    CutVertexId id;
    id.dim = 3;
    id.feature = {gridVertexId(cell.x(), cell.y(), cell.z()), tet, 0};
    id.planeCount = 2;
    id.planes[0] = 1;
    id.planes[1] = plane;
    return id;
}

struct Builder
{
    CutCellGeometry g;
    uint32_t add(const CutVertexId& id, const dvec3& p)
    {
        g.vertexIds.push_back(id);
        g.indexPositions.push_back(p);
        return uint32_t(g.vertexIds.size() - 1);
    }
    void tri(uint32_t a, uint32_t b, uint32_t c)
    {
        g.indices.insert(g.indices.end(), {a, b, c});
        g.cap.push_back(0);
    }
};

/// A tetrahedron at `at` (each face facing away from the fourth corner):
/// corners 0-2 inside tet 1 of `cell` (0, 0, 0), corner 3 too, or with
/// `cornerInFace` a vertex inside the tet face (0,0,0), (0,1,0), (0,1,1) of
/// the cell face x = 0, so that the tetrahedron is not the cell's own shell.
void addTetrahedron(Builder& b, const std::array<dvec3, 4>& at, uint64_t firstPlane, bool cornerInFace = false)
{
    const Coord cell(0, 0, 0);
    std::array<uint32_t, 4> v{};
    for (int i = 0; i < 4; ++i)
        v[size_t(i)] = b.add(i == 3 && cornerInFace ? faceVertex({0, 0, 0}, {0, 1, 0}, {0, 1, 1}, 1, firstPlane + 3)
                                                    : innerVertex(cell, 1, firstPlane + uint64_t(i)),
                             at[size_t(i)]);
    for (int l = 0; l < 4; ++l) {
        std::array<int, 3> f{};
        for (int i = 0, n = 0; i < 4; ++i)
            if (i != l) f[size_t(n++)] = i;
        const dvec3 nrm = glm::cross(at[size_t(f[1])] - at[size_t(f[0])], at[size_t(f[2])] - at[size_t(f[0])]);
        if (glm::dot(nrm, at[size_t(l)] - at[size_t(f[0])]) > 0) std::swap(f[1], f[2]);
        b.tri(v[size_t(f[0])], v[size_t(f[1])], v[size_t(f[2])]);
    }
}

using KeyEdge = std::pair<CutVertexId, CutVertexId>;
struct KeyEdgeLess
{
    bool operator()(const KeyEdge& a, const KeyEdge& b) const
    {
        if (a.first < b.first) return true;
        if (b.first < a.first) return false;
        return a.second < b.second;
    }
};

/// Directed edges of `g` by vertex name, with their use counts.
std::map<KeyEdge, int, KeyEdgeLess> directedEdges(const CutCellGeometry& g)
{
    std::map<KeyEdge, int, KeyEdgeLess> e;
    for (size_t t = 0; t + 2 < g.indices.size(); t += 3)
        for (int k = 0; k < 3; ++k)
            ++e[{g.vertexIds[g.indices[t + size_t(k)]], g.vertexIds[g.indices[t + size_t((k + 1) % 3)]]}];
    return e;
}

/// The edges used once with no reverse: the cell's boundary.
std::set<KeyEdge, KeyEdgeLess> boundary(const CutCellGeometry& g)
{
    const auto e = directedEdges(g);
    std::set<KeyEdge, KeyEdgeLess> b;
    for (const auto& [edge, n] : e) {
        EXPECT_EQ(n, 1) << "an edge used twice the same way";
        if (!e.count({edge.second, edge.first})) b.insert(edge);
    }
    return b;
}

/// Triangles whose float world corners are degenerate or face against
/// their exact orientation.
size_t foldedInFloat(const CutCellGeometry& g, const dvec3& origin, const dvec3& spacing)
{
    size_t n = 0;
    auto world = [&](uint32_t v) { return origin + spacing * g.indexPositions[v]; };
    // Through float storage: GCC 12.2 at -O2 folds dvec3(double(float(x)), ..)
    // away for the lanes it vectorises (FloatRepair.cpp, repairFloatFolds).
    auto rounded = [](const dvec3& p) {
        volatile float f[3] = {float(p.x), float(p.y), float(p.z)};
        return dvec3(f[0], f[1], f[2]);
    };
    for (size_t t = 0; t + 2 < g.indices.size(); t += 3) {
        const dvec3 a = world(g.indices[t]), b = world(g.indices[t + 1]), c = world(g.indices[t + 2]);
        const dvec3 exact = glm::cross(b - a, c - a);
        const dvec3 written = glm::cross(rounded(b) - rounded(a), rounded(c) - rounded(a));
        if (!(glm::dot(exact, written) > 0.0)) ++n;
    }
    return n;
}

/// The plane z = 0.5 across cell (0,0,0) with two inner vertices p, r a
/// distance d apart (x), fanned so that two slivers lie between them.
CutCellGeometry twoInnerVertices(double d)
{
    Builder b;
    const Coord cell(0, 0, 0);
    const uint32_t A = b.add(edgeVertex({0, 0, 0}, {0, 0, 1}, 1), {0, 0, 0.5});
    const uint32_t B = b.add(edgeVertex({1, 0, 0}, {1, 0, 1}, 1), {1, 0, 0.5});
    const uint32_t C = b.add(edgeVertex({1, 1, 0}, {1, 1, 1}, 1), {1, 1, 0.5});
    const uint32_t D = b.add(edgeVertex({0, 1, 0}, {0, 1, 1}, 1), {0, 1, 0.5});
    const uint32_t p = b.add(innerVertex(cell, 0, 100), {0.5, 0.5, 0.5});
    const uint32_t r = b.add(innerVertex(cell, 0, 101), {0.5 + d, 0.5, 0.5});
    b.tri(A, B, r);
    b.tri(B, C, r);
    b.tri(C, p, r);
    b.tri(C, D, p);
    b.tri(D, A, p);
    b.tri(A, r, p);
    return b.g;
}

TEST(FloatFolds, InnerVerticesAFloatStepApartBecomeOneAndTheBoundaryStays)
{
    // At 1000 mm a float step is 6.1e-5 mm: 1e-7 mm apart, p and r round
    // to one point and both slivers between them collapse in float.
    const dvec3 origin(1000.0), spacing(1.0);
    CutCellGeometry g = twoInnerVertices(1e-7);
    ASSERT_EQ(foldedInFloat(g, origin, spacing), 2u); // the test's premise
    const auto before = boundary(g);
    EXPECT_EQ(repairFloatFolds(Coord(0, 0, 0), openvdb::Vec3d(1000.0), openvdb::Vec3d(1.0), g), 1u);
    EXPECT_EQ(g.vertexIds.size(), 5u);
    EXPECT_EQ(g.indices.size(), 12u);
    EXPECT_EQ(foldedInFloat(g, origin, spacing), 0u);
    EXPECT_EQ(boundary(g), before); // the seam with the next cells is as it was
    for (uint32_t i : g.indices) EXPECT_LT(i, g.vertexIds.size());
}

// A fan whose centre lies 2e-5 mm off one of its edges in y, under half a
// float step at 1000 mm (3.05e-5): no edge is short, but the triangle on
// that edge has no area once written. The repair must judge the rounded
// positions in every axis: with GCC 12.2 at -O2 it used to see x and y
// unrounded (the vectorised round trip double(float(x)) folded away) and
// kept the triangle, which the local check then refused (1 mm head, a tip
// line a float step above y = 249: CutPropsDefects.ACapStripThinnerThanAFloatStepAtTheTipIsMended).
TEST(FloatFolds, ACentreThatRoundsOntoAnEdgeOfItsFanIsCollapsedInEveryAxis)
{
    const Coord cell(0, 0, 0);
    const dvec3 origin(1000.0), spacing(1.0);
    for (int axis = 0; axis < 2; ++axis) { // the centre off its edge in y, then (the fan turned) in x
        auto at = [&](double u, double v) { return axis == 0 ? dvec3(u, v, 0.5) : dvec3(v, u, 0.5); };
        auto edge = [&](int u, int v) {
            const Coord a = axis == 0 ? Coord(u, v, 0) : Coord(v, u, 0);
            return edgeVertex(a, a + Coord(0, 0, 1), 1);
        };
        Builder b;
        const uint32_t A = b.add(edge(0, 0), at(0, 0)), B = b.add(edge(1, 0), at(1, 0));
        const uint32_t C = b.add(edge(1, 1), at(1, 1)), D = b.add(edge(0, 1), at(0, 1));
        const uint32_t p = b.add(innerVertex(cell, 0, 100), at(0.5, 2e-5));
        if (axis == 0) {
            for (auto [u, v] : {std::pair{A, B}, {B, C}, {C, D}, {D, A}}) b.tri(u, v, p);
        } else { // mirrored: the same fan, the other way round
            for (auto [u, v] : {std::pair{B, A}, {C, B}, {D, C}, {A, D}}) b.tri(u, v, p);
        }
        CutCellGeometry g = b.g;
        ASSERT_EQ(foldedInFloat(g, origin, spacing), 1u) << axis; // the premise: (A, B, p) has no area written
        const auto before = boundary(g);
        EXPECT_EQ(repairFloatFolds(cell, openvdb::Vec3d(1000.0), openvdb::Vec3d(1.0), g), 1u) << axis;
        EXPECT_EQ(g.vertexIds.size(), 4u) << axis;
        EXPECT_EQ(g.indices.size(), 6u) << axis;
        EXPECT_EQ(foldedInFloat(g, origin, spacing), 0u) << axis;
        EXPECT_EQ(boundary(g), before) << axis;
    }
}

// A tetrahedron of the cell's own with an edge far below a float step (a
// spike of solid between three prisms pivoting on its tip: the 2 mm head at
// 0.8 x 0.8 x 2.4 mm, kerf 0.5, seed 10054, 2e-3 voxel thin). Collapsing
// that edge keeps the link condition, but the two faces off it then lie on
// each other facing opposite ways, a shell of no volume that the local
// check refused as a self-contact. The whole tetrahedron goes (now by the
// shell rule, AShellOfTheCellsOwnThinnerThanAFloatStepGoesAsAWhole, before
// any collapse: its four vertices); the rest of the cell stays as it was.
TEST(FloatFolds, ATetrahedronWithAnEdgeBelowAFloatStepGoesAsAWhole)
{
    const Coord cell(0, 0, 0);
    CutCellGeometry g = twoInnerVertices(0.25); // a square of plane z = 0.5, nothing to mend
    Builder b;
    b.g = g;
    const size_t squareTris = g.indices.size() / 3;
    addTetrahedron(b, {dvec3(0.6, 0.6, 0.2), dvec3(0.6 + 1e-7, 0.6, 0.2), dvec3(0.6, 0.61, 0.2), dvec3(0.3, 0.3, 0.3)},
                   200);
    g = b.g;
    const dvec3 origin(1000.0), spacing(1.0);
    ASSERT_EQ(foldedInFloat(g, origin, spacing), 2u); // the premise: the two faces on the short edge
    const auto before = boundary(g);
    EXPECT_EQ(repairFloatFolds(cell, openvdb::Vec3d(1000.0), openvdb::Vec3d(1.0), g), 4u);
    EXPECT_EQ(g.indices.size() / 3, squareTris) << "the tetrahedron is not gone";
    for (uint32_t i : g.indices) EXPECT_LT(i, uint32_t(6)) << "a triangle of the tetrahedron stayed";
    EXPECT_EQ(boundary(g), before);
    EXPECT_EQ(foldedInFloat(g, origin, spacing), 0u);
}

// A tetrahedron of the cell's own whose edges are all longer than a short
// edge, one face of no area once written (a point 1e-6 mm off the line of
// two others at 1000 mm, where a float step is 6.1e-5). The link condition
// holds for each of its edges, but every collapse crushes it into two
// triangles facing each other, a shell of no volume (2 mm head, kerf 0,
// sawing across the blade, seed 78105). None is made: it stays whole.
TEST(FloatFolds, ATetrahedronIsNotCrushedIntoTwoTriangles)
{
    const Coord cell(0, 0, 0);
    Builder b;
    // (A corner in a cell face: wholly the cell's own, it would go by the
    // shell rule first.)
    addTetrahedron(b, {dvec3(0.5, 0.5, 0.5), dvec3(0.6, 0.5, 0.5), dvec3(0.55, 0.5 + 1e-6, 0.5), dvec3(0.0, 0.6, 0.55)},
                   300, true);
    CutCellGeometry g = b.g;
    const dvec3 origin(1000.0), spacing(1.0);
    ASSERT_EQ(foldedInFloat(g, origin, spacing), 1u); // the premise: a fold to mend, no short edge
    repairFloatFolds(cell, openvdb::Vec3d(1000.0), openvdb::Vec3d(1.0), g);
    const size_t n = g.indices.size() / 3;
    for (size_t t = 0; t < n; ++t)
        for (size_t u = t + 1; u < n; ++u) {
            std::array<uint32_t, 3> x{g.indices[3 * t], g.indices[3 * t + 1], g.indices[3 * t + 2]};
            std::array<uint32_t, 3> y{g.indices[3 * u], g.indices[3 * u + 2], g.indices[3 * u + 1]};
            std::sort(x.begin(), x.end());
            std::sort(y.begin(), y.end());
            EXPECT_NE(x, y) << "triangles " << t << " and " << u << " lie on each other";
        }
    EXPECT_EQ(n, 4u);
    EXPECT_TRUE(boundary(g).empty());
}

// A shell of the cell's own (every vertex inside the cell, off its faces)
// thinner than a short edge goes as a whole, and only such a shell: a
// tetrahedron 1e-7 voxel thick at 1000 mm, where a float step is 6.1e-5 (2
// mm head, kerf 0, sawing across the blade, seeds 78113 and 78119: one 1e-7
// mm thick between three slits' sides, judged inside the fragment whose
// sheets it lay on). One as thin with a corner in a cell face, and one of
// the cell's own a micron thick, stay.
TEST(FloatFolds, AShellOfTheCellsOwnThinnerThanAFloatStepGoesAsAWhole)
{
    const Coord cell(0, 0, 0);
    const std::array<dvec3, 4> thin{dvec3(0.2, 0.2, 0.2), dvec3(0.3, 0.2, 0.2), dvec3(0.25, 0.3, 0.2),
                                    dvec3(0.25, 0.25, 0.2 + 1e-7)};
    std::array<dvec3, 4> thick = thin;
    thick[3].z = 0.2 + 1e-3;
    struct Case
    {
        std::array<dvec3, 4> at;
        bool inFace;
        size_t removed;
    };
    for (const Case& c : {Case{thin, false, 4}, Case{thin, true, 0}, Case{thick, false, 0}}) {
        SCOPED_TRACE(std::string(c.inFace ? "a corner in a face" : "the cell's own") + ", removed " + std::to_string(c.removed));
        std::array<dvec3, 4> at = c.at;
        if (c.inFace) at[3] = dvec3(0.0, 0.6, 0.55);
        Builder b;
        b.g = twoInnerVertices(0.25);
        addTetrahedron(b, at, 400, c.inFace);
        CutCellGeometry g = b.g;
        const size_t before = g.indices.size() / 3;
        const size_t removed = repairFloatFolds(cell, openvdb::Vec3d(1000.0), openvdb::Vec3d(1.0), g);
        if (c.inFace) { // the thin one folds once written; whatever mends that, it is not dropped whole
            EXPECT_GE(g.indices.size() / 3, before - 2);
            continue;
        }
        EXPECT_EQ(removed, c.removed);
        EXPECT_EQ(g.indices.size() / 3, before - (c.removed ? 4 : 0));
        EXPECT_EQ(g.vertexIds.size(), 10 - c.removed);
        for (uint32_t i : g.indices) EXPECT_LT(i, uint32_t(g.vertexIds.size()));
    }
}

TEST(FloatFolds, WhatFloatHoldsApartIsLeftAlone)
{
    // Near the origin a float step is 6e-8 mm; 1e-3 voxel is thousands.
    for (double d : {1e-3, 1e-5}) {
        CutCellGeometry g = twoInnerVertices(d);
        const CutCellGeometry copy = g;
        EXPECT_EQ(repairFloatFolds(Coord(0, 0, 0), openvdb::Vec3d(0.0), openvdb::Vec3d(1.0), g), 0u) << d;
        EXPECT_EQ(g.vertexIds, copy.vertexIds);
        EXPECT_EQ(g.indices, copy.indices);
        EXPECT_EQ(g.indexPositions, copy.indexPositions);
    }
}

TEST(FloatFolds, CopiesOfOnePointStayApart)
{
    // The same two inner vertices as side copies (a zero-kerf cut's two
    // sides): different tags, never joined, even where float folds them.
    CutCellGeometry g = twoInnerVertices(1e-7);
    g.vertexIds[5] = g.vertexIds[4];
    g.vertexIds[4].tagCount = g.vertexIds[5].tagCount = 1;
    g.vertexIds[4].tags[0] = 7u << 1;
    g.vertexIds[5].tags[0] = (7u << 1) | 1u;
    const CutCellGeometry copy = g;
    EXPECT_EQ(repairFloatFolds(Coord(0, 0, 0), openvdb::Vec3d(1000.0), openvdb::Vec3d(1.0), g), 0u);
    EXPECT_EQ(g.indices, copy.indices);
}

// Two different points a float step apart, one on a zero-kerf slit's minus
// side and one off the slit (or on the same side of it and of another quad's
// slit too) lie on one sheet: a round joins them as any others (tooth at
// 400, kerf 0, a saw slid along its blade, seed 75409, stroke 1, quad 62: a
// slit chord's midpoint {q54-}, the junction point {q54-, q55+} and a point
// of quad 55's plane {} within 1.5e-5 mm, their triangle of no area once
// written, and no pair of them could be joined). Points on opposite sides of
// one slit, and copies of a pinch, stay apart.
TEST(FloatFolds, PointsOnOneSideOfASlitAFloatStepApartBecomeOne)
{
    auto tagged = [](const std::vector<uint64_t>& tags, CutVertexId v) {
        v.tagCount = uint8_t(tags.size());
        size_t i = 0;
        for (uint64_t t : tags) v.tags[i++] = t;
        return v;
    };
    struct Case
    {
        std::vector<uint64_t> p, r;
        size_t joined;
    };
    const uint64_t minus7 = 7u << 1 | 1u, plus7 = 7u << 1, plus9 = 9u << 1, kPinch = mtcut::cutter::remesh_detail::kPinchTag;
    const std::vector<Case> cases{Case{{minus7}, {}, 1}, Case{{minus7}, {minus7, plus9}, 1}, Case{{}, {plus9}, 1},
                                  Case{{minus7}, {plus7}, 0}, Case{{minus7}, {minus7 | kPinch}, 0},
                                  Case{{kPinch | 1u}, {}, 0}};
    for (const Case& c : cases) {
        CutCellGeometry g = twoInnerVertices(1e-7);
        g.vertexIds[4] = tagged(c.p, g.vertexIds[4]);
        g.vertexIds[5] = tagged(c.r, g.vertexIds[5]);
        const size_t tagsP = c.p.size(), tagsR = c.r.size();
        SCOPED_TRACE("tags " + std::to_string(tagsP) + " and " + std::to_string(tagsR) + ", joined " +
                     std::to_string(c.joined));
        const dvec3 origin(1000.0), spacing(1.0);
        ASSERT_EQ(foldedInFloat(g, origin, spacing), 2u); // the premise
        const CutCellGeometry copy = g;
        const auto before = boundary(g);
        EXPECT_EQ(repairFloatFolds(Coord(0, 0, 0), openvdb::Vec3d(1000.0), openvdb::Vec3d(1.0), g), c.joined);
        if (c.joined) {
            EXPECT_EQ(g.vertexIds.size(), 5u);
            EXPECT_EQ(foldedInFloat(g, origin, spacing), 0u);
            EXPECT_EQ(boundary(g), before);
        } else {
            EXPECT_EQ(g.indices, copy.indices);
        }
    }
}

/// The plane y = 0.5 across cell (cx,0,0), cx = 0 or 1, whose boundary on
/// the face x = 1 they share holds two vertices d apart (z): two vertices
/// inside a tet face there, or (onDiagonal) the lower one on the face's
/// diagonal from (1,0,0) to (1,1,1), a grid edge only these two cells have.
CutCellGeometry faceShared(int cx, double d, bool onDiagonal = false)
{
    Builder b;
    const Coord f0(1, 0, 0), f1(1, 1, 0), f2(1, 1, 1); // a tet face in the cell face x = 1
    const CutVertexId F1 = onDiagonal ? edgeVertex(f0, f2, 200) : faceVertex(f0, f1, f2, 1, 200);
    const CutVertexId F2 = faceVertex(f0, f1, f2, 1, 201);
    const double z1 = onDiagonal ? 0.5 : 0.4;
    const CutVertexId bottom = edgeVertex({1, 0, 0}, {1, 1, 0}, 1), top = edgeVertex({1, 0, 1}, {1, 1, 1}, 1);
    if (cx == 0) {
        const uint32_t P00 = b.add(edgeVertex({0, 0, 0}, {0, 1, 0}, 1), {0, 0.5, 0});
        const uint32_t P10 = b.add(bottom, {1, 0.5, 0});
        const uint32_t a = b.add(F1, {1, 0.5, z1}), c = b.add(F2, {1, 0.5, z1 + d});
        const uint32_t P11 = b.add(top, {1, 0.5, 1});
        const uint32_t P01 = b.add(edgeVertex({0, 0, 1}, {0, 1, 1}, 1), {0, 0.5, 1});
        b.tri(P00, P10, a);
        b.tri(P00, a, c);
        b.tri(P00, c, P11);
        b.tri(P00, P11, P01);
    } else {
        const uint32_t Q10 = b.add(bottom, {1, 0.5, 0});
        const uint32_t Q20 = b.add(edgeVertex({2, 0, 0}, {2, 1, 0}, 1), {2, 0.5, 0});
        const uint32_t Q21 = b.add(edgeVertex({2, 0, 1}, {2, 1, 1}, 1), {2, 0.5, 1});
        const uint32_t Q11 = b.add(top, {1, 0.5, 1});
        const uint32_t c = b.add(F2, {1, 0.5, z1 + d}), a = b.add(F1, {1, 0.5, z1});
        b.tri(Q20, Q21, Q11);
        b.tri(Q20, Q11, c);
        b.tri(Q20, c, a);
        b.tri(Q20, a, Q10);
    }
    return b.g;
}

/// faceShared's left cell with its triangle (P00, a, c) raised into a tent:
/// three triangles round a vertex T inside the cell, a little off the plane,
/// so a and c have two common neighbours (T and P00) where the edge a-c has
/// one apex (T). Merging c into a needs the tent to go too.
CutCellGeometry tentAtFace(double d)
{
    Builder b;
    const Coord f0(1, 0, 0), f1(1, 1, 0), f2(1, 1, 1);
    const double z1 = 0.4;
    const uint32_t P00 = b.add(edgeVertex({0, 0, 0}, {0, 1, 0}, 1), {0, 0.5, 0});
    const uint32_t P10 = b.add(edgeVertex({1, 0, 0}, {1, 1, 0}, 1), {1, 0.5, 0});
    const uint32_t a = b.add(faceVertex(f0, f1, f2, 1, 200), {1, 0.5, z1});
    const uint32_t c = b.add(faceVertex(f0, f1, f2, 1, 201), {1, 0.5, z1 + d});
    const uint32_t P11 = b.add(edgeVertex({1, 0, 1}, {1, 1, 1}, 1), {1, 0.5, 1});
    const uint32_t P01 = b.add(edgeVertex({0, 0, 1}, {0, 1, 1}, 1), {0, 0.5, 1});
    const uint32_t T = b.add(innerVertex(Coord(0, 0, 0), 3, 201), {1 - 2e-3, 0.5 - 2e-3, z1 + 0.5 * d});
    b.tri(P00, P10, a);
    b.tri(a, c, T);
    b.tri(a, T, P00);
    b.tri(c, P00, T);
    b.tri(P00, c, P11);
    b.tri(P00, P11, P01);
    return b.g;
}

/// As faceShared, but one vertex inside the face x = 1, d (z) above the
/// seam's vertex on the cube edge z = 0 of that face (which four cells hold).
CutCellGeometry faceAboveEdge(int cx, double d)
{
    Builder b;
    const CutVertexId F = faceVertex(Coord(1, 0, 0), Coord(1, 1, 0), Coord(1, 1, 1), 1, 201);
    const CutVertexId bottom = edgeVertex({1, 0, 0}, {1, 1, 0}, 1), top = edgeVertex({1, 0, 1}, {1, 1, 1}, 1);
    if (cx == 0) {
        const uint32_t P00 = b.add(edgeVertex({0, 0, 0}, {0, 1, 0}, 1), {0, 0.5, 0});
        const uint32_t P10 = b.add(bottom, {1, 0.5, 0});
        const uint32_t c = b.add(F, {1, 0.5, d});
        const uint32_t P11 = b.add(top, {1, 0.5, 1});
        const uint32_t P01 = b.add(edgeVertex({0, 0, 1}, {0, 1, 1}, 1), {0, 0.5, 1});
        b.tri(P00, P10, c);
        b.tri(P00, c, P11);
        b.tri(P00, P11, P01);
    } else {
        const uint32_t Q10 = b.add(bottom, {1, 0.5, 0});
        const uint32_t Q20 = b.add(edgeVertex({2, 0, 0}, {2, 1, 0}, 1), {2, 0.5, 0});
        const uint32_t Q21 = b.add(edgeVertex({2, 0, 1}, {2, 1, 1}, 1), {2, 0.5, 1});
        const uint32_t Q11 = b.add(top, {1, 0.5, 1});
        const uint32_t c = b.add(F, {1, 0.5, d});
        b.tri(Q20, Q21, Q11);
        b.tri(Q20, Q11, c);
        b.tri(Q20, c, Q10);
    }
    return b.g;
}

/// The edges of `b` that lie in the face x = 1 (both ends there).
std::set<KeyEdge, KeyEdgeLess> onFaceX1(const std::set<KeyEdge, KeyEdgeLess>& b, const CutCellGeometry& g)
{
    std::map<CutVertexId, double> x;
    for (size_t i = 0; i < g.vertexIds.size(); ++i) x[g.vertexIds[i]] = g.indexPositions[i].x;
    std::set<KeyEdge, KeyEdgeLess> out;
    for (const KeyEdge& e : b)
        if (x.at(e.first) == 1.0 && x.at(e.second) == 1.0) out.insert(e);
    return out;
}

/// Do the two cells weld along x = 1 (each edge there once each way)?
bool seamMatches(const CutCellGeometry& l, const CutCellGeometry& r)
{
    const auto bl = onFaceX1(boundary(l), l), br = onFaceX1(boundary(r), r);
    if (bl.size() != br.size() || bl.empty()) return false;
    for (const KeyEdge& e : bl)
        if (!br.count({e.second, e.first})) return false;
    return true;
}

TEST(FloatFolds, FaceVerticesAFloatStepApartBecomeOneInBothCells)
{
    const openvdb::Vec3d origin(1000.0), spacing(1.0);
    CutCellGeometry left = faceShared(0, 1e-7), right = faceShared(1, 1e-7);
    // Premise: the two cells weld along x = 1 (each edge there once each way).
    ASSERT_TRUE(seamMatches(left, right));
    ASSERT_EQ(foldedInFloat(left, dvec3(1000.0), dvec3(1.0)), 1u);
    EXPECT_EQ(repairFloatFolds(Coord(0, 0, 0), origin, spacing, left), 1u);
    EXPECT_EQ(repairFloatFolds(Coord(1, 0, 0), origin, spacing, right), 1u);
    EXPECT_EQ(left.vertexIds.size(), 5u);
    EXPECT_EQ(right.vertexIds.size(), 5u);
    EXPECT_EQ(left.indices.size(), 9u);
    EXPECT_EQ(right.indices.size(), 9u);
    EXPECT_TRUE(seamMatches(left, right)) << "the cells of the face judged it differently";
    EXPECT_EQ(foldedInFloat(left, dvec3(1000.0), dvec3(1.0)), 0u);
    EXPECT_EQ(foldedInFloat(right, dvec3(1000.0), dvec3(1.0)), 0u);
    // Kept apart where float keeps them apart.
    CutCellGeometry far = faceShared(0, 1e-2);
    EXPECT_EQ(repairFloatFolds(Coord(0, 0, 0), origin, spacing, far), 0u);
    EXPECT_EQ(far.vertexIds.size(), 6u);
}

// The two cells of a face judge a face pair by the face's largest world
// coordinate, not each by its own: across the face x = 1001 mm the left cell
// reaches x = 1001 and the right one x = 1002, so two face vertices between
// their two thresholds apart were joined in the right cell only, and the
// seam opened (tooth seed 1002, kerf 0.5, at z = 98 mm, refused).
// A vertex on a face's diagonal is inside that face as much as one in a tet
// face there: only the two cells of the face have it. The 1 mm head at kerf
// 0 (random strokes, seed 2002) had a slit copy of an iso vertex on a
// diagonal 2.5e-5 voxel from a cap vertex in the face, at z = 1241 mm (a float
// step there is 1.2e-4 mm): they rounded to one point and the triangle they
// spanned with an inner vertex rounded onto the face to zero area (refused).
TEST(FloatFolds, ADiagonalVertexAndAFaceVertexAFloatStepApartBecomeOneInBothCells)
{
    const openvdb::Vec3d origin(1000.0), spacing(1.0);
    CutCellGeometry left = faceShared(0, 1e-7, true), right = faceShared(1, 1e-7, true);
    ASSERT_TRUE(seamMatches(left, right));
    ASSERT_EQ(foldedInFloat(left, dvec3(1000.0), dvec3(1.0)), 1u);
    EXPECT_EQ(repairFloatFolds(Coord(0, 0, 0), origin, spacing, left), 1u);
    EXPECT_EQ(repairFloatFolds(Coord(1, 0, 0), origin, spacing, right), 1u);
    EXPECT_TRUE(seamMatches(left, right)) << "the cells of the face judged it differently";
    EXPECT_EQ(foldedInFloat(left, dvec3(1000.0), dvec3(1.0)), 0u);
    EXPECT_EQ(foldedInFloat(right, dvec3(1000.0), dvec3(1.0)), 0u);
    // The diagonal's vertex (the lesser name, dim 1) stays in both.
    for (const CutCellGeometry* g : {&left, &right}) {
        size_t onDiagonal = 0;
        for (const CutVertexId& id : g->vertexIds) onDiagonal += id.dim == 1 && id.planes[0] == 200;
        EXPECT_EQ(onDiagonal, 1u);
    }
}

// A blade plane 3e-5 mm from a grid vertex at z = 1045 mm (a float step
// there is 1.2e-4 mm): its vertices on the edges and faces around the grid
// vertex go onto it (within two float steps at its largest coordinate), a
// plain marching-tetrahedra vertex (the uncut mesh's) and anything farther
// stay where they are.
TEST(FloatFolds, NewVerticesWithinTwoFloatStepsOfAGridVertexGoOntoIt)
{
    const openvdb::Vec3d origin(0.0, 0.0, 1000.0), spacing(1.0);
    const double near = 2.0 * 1045.0 * double(std::numeric_limits<float>::epsilon()); // 2.5e-4 mm
    const Coord g(221, 188, 45), below(221, 188, 44), side(221, 187, 45);
    Builder b;
    const uint32_t onEdge = b.add(edgeVertex(below, g, 200), {221, 188, 45 - 3e-5});
    const uint32_t farOnEdge = b.add(edgeVertex(below, g, 201), {221, 188, 45 - 1.01 * near});
    const uint32_t iso = b.add(edgeVertex(below, g, 1), {221, 188, 45 - 1e-5});
    const uint32_t onFace = b.add(faceVertex(below, side, g, 1, 200), {221, 188 - 1e-4, 45 - 1e-4});
    const uint32_t inside = b.add(innerVertex(Coord(220, 187, 44), 2, 200), {221 - 0.99 * near, 188, 45});
    b.tri(onEdge, farOnEdge, onFace);
    b.tri(iso, onFace, inside);
    const CutCellGeometry before = b.g;
    EXPECT_EQ(snapToGridVertices(origin, spacing, b.g), 3u);
    const dvec3 at(221, 188, 45);
    EXPECT_EQ(b.g.indexPositions[onEdge], at);
    EXPECT_EQ(b.g.indexPositions[onFace], at);
    EXPECT_EQ(b.g.indexPositions[inside], at);
    EXPECT_EQ(b.g.indexPositions[farOnEdge], before.indexPositions[farOnEdge]);
    EXPECT_EQ(b.g.indexPositions[iso], before.indexPositions[iso]);
    EXPECT_EQ(b.g.indices, before.indices);
    EXPECT_EQ(b.g.vertexIds, before.vertexIds);
    // Near the origin a float step is smaller, and so is the reach.
    Builder o;
    o.add(edgeVertex(Coord(0, 0, 0), Coord(0, 0, 1), 200), {0, 0, 1 - 3e-5});
    EXPECT_EQ(snapToGridVertices(openvdb::Vec3d(0.0), spacing, o.g), 0u);
}

// A vertex inside a face a float step from a vertex on the face's edge
// (1 mm head, kerf 0.5, seed 2002: 3e-5 mm above a cube edge at z = 1226 mm;
// rounded onto the edge past the edge's vertex, the segment to it touched
// the cells below there): both cells of the face put it onto the edge's
// vertex, which the two other cells around the edge keep as it is.
TEST(FloatFolds, AFaceVertexAFloatStepFromTheFacesEdgeVertexBecomesItInBothCells)
{
    const openvdb::Vec3d origin(1000.0), spacing(1.0);
    CutCellGeometry left = faceAboveEdge(0, 1e-7), right = faceAboveEdge(1, 1e-7);
    ASSERT_TRUE(seamMatches(left, right));
    ASSERT_EQ(foldedInFloat(left, dvec3(1000.0), dvec3(1.0)), 1u);
    EXPECT_EQ(repairFloatFolds(Coord(0, 0, 0), origin, spacing, left), 1u);
    EXPECT_EQ(repairFloatFolds(Coord(1, 0, 0), origin, spacing, right), 1u);
    EXPECT_TRUE(seamMatches(left, right)) << "the cells of the face judged it differently";
    for (const CutCellGeometry* g : {&left, &right}) {
        EXPECT_EQ(g->vertexIds.size(), 4u);
        EXPECT_EQ(foldedInFloat(*g, dvec3(1000.0), dvec3(1.0)), 0u);
        for (const CutVertexId& id : g->vertexIds) EXPECT_NE(id.dim, 2) << "the face vertex is gone";
    }
    // Apart where float holds them apart.
    CutCellGeometry far = faceAboveEdge(0, 1e-2);
    EXPECT_EQ(repairFloatFolds(Coord(0, 0, 0), origin, spacing, far), 0u);
}

TEST(FloatFolds, BothCellsOfAFaceJudgeItsPairByTheFace)
{
    const openvdb::Vec3d origin(1000.0), spacing(1.0);
    const double step = double(std::numeric_limits<float>::epsilon());
    const double byFace = 2.0 * step * 1001.0, byRightCell = 2.0 * step * 1002.0;
    for (const double d : {0.5 * (byFace + byRightCell), 0.999 * byFace}) {
        CutCellGeometry left = faceShared(0, d), right = faceShared(1, d);
        ASSERT_TRUE(seamMatches(left, right));
        const size_t l = repairFloatFolds(Coord(0, 0, 0), origin, spacing, left);
        const size_t r = repairFloatFolds(Coord(1, 0, 0), origin, spacing, right);
        EXPECT_EQ(l, r) << "d = " << d;
        EXPECT_EQ(l, d < byFace ? 1u : 0u) << "d = " << d;
        EXPECT_TRUE(seamMatches(left, right)) << "the cells of the face judged it differently, d = " << d;
    }
}

} // namespace

// The face rule in a cell where the pair closes a small tent of the cell's
// own (2 mm head, kerf 0.5, seed 3023, at z = 1018 mm: two face vertices of
// near-coincident end planes of two quads 9e-5 mm apart, and a vertex inside
// the tet below them joined to both and to a third). The cell above merged
// them; this one could not (the link condition: a and c had a second common
// neighbour), and the seam opened there (refused). The tent's triangles now
// cancel in pairs as the pair becomes one, and its inner vertex goes.
TEST(FloatFolds, AFacePairClosingATentOfTheCellsOwnBecomesOneWithTheTentGone)
{
    const openvdb::Vec3d origin(1000.0), spacing(1.0);
    CutCellGeometry left = tentAtFace(1e-7), right = faceShared(1, 1e-7);
    ASSERT_TRUE(seamMatches(left, right));
    EXPECT_EQ(repairFloatFolds(Coord(1, 0, 0), origin, spacing, right), 1u);
    EXPECT_EQ(repairFloatFolds(Coord(0, 0, 0), origin, spacing, left), 1u);
    EXPECT_TRUE(seamMatches(left, right)) << "the cells of the face judged it differently";
    EXPECT_EQ(left.indices.size(), 9u);
    EXPECT_EQ(left.vertexIds.size(), 5u);
    for (const CutVertexId& id : left.vertexIds) EXPECT_NE(id.dim, 3) << "the tent's vertex is still there";
    (void)boundary(left); // no edge used twice the same way
    EXPECT_EQ(foldedInFloat(left, dvec3(1000.0), dvec3(1.0)), 0u);
    // Apart where float holds them apart: the tent stays.
    CutCellGeometry far = tentAtFace(1e-2);
    EXPECT_EQ(repairFloatFolds(Coord(0, 0, 0), origin, spacing, far), 0u);
    EXPECT_EQ(far.indices.size(), 18u);
}

// A tent of three triangles over a triangle of a cell face, its apex inside
// the cell 6.1e-5 mm below the face (1 mm head, kerf 0.5, seed 9202, cell
// (205, 295, 134) at z = 1135 mm, where a float step is 1.2e-4 mm: the
// face triangle bounded by the isosurface's line, a kerf plane's line and
// the face's diagonal). Rounded, the apex lies in the face outside that
// triangle, and the tent's triangles overlap there. Its collapses all lay
// a triangle into the face, which a round refuses; when the cell's own
// triangles cross (the local check's second pass), the shortest short edge
// goes anyway and the triangle left in the face is marked (intoFace). Not
// without crossings: a cut that passes its check is not touched.
TEST(FloatFolds, ATentOverAFaceTriangleThatCrossesOnceWrittenFlattensIntoTheFace)
{
    const openvdb::Vec3d origin(0.0, 0.0, 1000.0), spacing(1.0);
    const Coord d0(206, 295, 135), d1(205, 296, 135); // the face z = 135's diagonal
    auto tent = [&] {
        Builder b;
        const uint32_t iso = b.add(edgeVertex(d0, d1, 1), {205.637860082305, 295.362139917695, 135.0});
        const uint32_t blade = b.add(edgeVertex(d0, d1, 200), {205.637780245954, 295.362219754046, 135.0});
        const uint32_t inFace =
            b.add(faceVertex(d0, d1, Coord(206, 296, 135), 1, 200), {205.638770076005, 295.366494887550, 135.0});
        const uint32_t apex =
            b.add(faceVertex(Coord(206, 296, 134), d0, d1, 1, 200), {205.637883342519, 295.362177652792, 134.999939004689});
        b.tri(inFace, iso, apex);
        b.tri(blade, inFace, apex);
        b.tri(iso, blade, apex);
        return b.g;
    };
    const Coord cell(205, 295, 134);
    CutCellGeometry g = tent();
    EXPECT_EQ(repairFloatFolds(cell, origin, spacing, g, false), 0u) << "a round lays no triangle into a face";
    EXPECT_EQ(g.indices.size(), 9u);
    EXPECT_EQ(repairFloatFolds(cell, origin, spacing, g, true), 1u);
    ASSERT_EQ(g.indices.size(), 3u) << "the tent flattens into one triangle";
    EXPECT_EQ(g.vertexIds.size(), 3u);
    for (const CutVertexId& id : g.vertexIds) EXPECT_TRUE(id.dim == 1 || id.feature[0] != gridVertexId(206, 296, 134));
    EXPECT_EQ(g.intoFace, std::vector<uint32_t>{0}) << "the triangle left in the face is marked";
    // Its edges are the tent's rim, each the same way round.
    const auto rim = directedEdges(tent());
    for (const auto& [edge, n] : directedEdges(g)) {
        EXPECT_EQ(n, 1);
        EXPECT_EQ(rim.count(edge), 1u);
    }
}

// Zero kerf has no crossings pass: a tent over a face triangle whose apex
// is written into the face on the line of two of the face's vertices, its
// triangle there of no area (2 mm head, kerf 0, sawing across the blade,
// seed 77707: the apex where two slits meet the isosurface, within a float
// step of the face z = 1170 mm, the two face vertices 3e-5 mm apart along
// x with different side tags, so the face rule keeps them apart; the update
// was refused). Every collapse of the apex lays the rest of the tent into
// the face, which a round refuses. Asked (flattenFoldedTents: the kernel
// asks it without kerf), the rounds' pass collapses the apex's shortest
// edge anyway and marks the triangle left in the face, whose edges are the
// tent's rim. A tent that float holds up is left alone; without the flag
// nothing changes.
TEST(FloatFolds, AFoldedTentOverAFaceTriangleFlattensAtZeroKerf)
{
    const openvdb::Vec3d origin(0.0, 0.0, 1000.0), spacing(1.0);
    const Coord cell(205, 295, 134), f0(205, 295, 135), f1(206, 295, 135), f2(205, 296, 135); // a tet face in z = 135
    auto tent = [&](double apexBelow) {
        Builder b;
        CutVertexId ia = faceVertex(f0, f1, f2, 1, 200), ib = faceVertex(f0, f1, f2, 200, 201);
        ia.tagCount = 1;
        ia.tags[0] = 200u << 1;
        ib.tagCount = 2;
        ib.tags[0] = 200u << 1;
        ib.tags[1] = 201u << 1;
        const uint32_t A = b.add(ia, {205.5, 295.3, 135.0});
        const uint32_t B = b.add(ib, {205.5 + 3.05e-5, 295.3, 135.0}); // two float steps along x
        const uint32_t C = b.add(faceVertex(f0, f1, f2, 1, 201), {205.3, 295.5, 135.0});
        const uint32_t P = b.add(innerVertex(cell, 1, 201), {205.5 + 1.5e-5, 295.3, 135.0 - apexBelow});
        b.tri(A, B, P);
        b.tri(B, C, P);
        b.tri(C, A, P);
        return b.g;
    };
    CutCellGeometry g = tent(1e-6);
    EXPECT_EQ(repairFloatFolds(cell, origin, spacing, g, false, false), 0u);
    EXPECT_EQ(g.indices.size(), 9u) << "without the flag a round lays no triangle into a face";
    EXPECT_EQ(repairFloatFolds(cell, origin, spacing, g, false, true), 1u);
    ASSERT_EQ(g.indices.size(), 3u) << "the tent flattens into one triangle";
    EXPECT_EQ(g.vertexIds.size(), 3u);
    for (const CutVertexId& id : g.vertexIds) EXPECT_EQ(id.dim, 2) << "the apex went";
    EXPECT_EQ(g.intoFace, std::vector<uint32_t>{0}) << "the triangle left in the face is marked";
    const auto rim = boundary(tent(1e-6));
    EXPECT_EQ(rim.size(), 3u);
    for (const auto& [edge, n] : directedEdges(g)) {
        EXPECT_EQ(n, 1);
        EXPECT_EQ(rim.count(edge), 1u);
    }
    CutCellGeometry high = tent(1e-2); // 1e-2 mm under the face: float holds it up
    EXPECT_EQ(repairFloatFolds(cell, origin, spacing, high, false, true), 0u);
    EXPECT_EQ(high.indices.size(), 9u);
}

// A spike in a cell face's section (tooth at 400, kerf 0.5, seed 9074,
// stroke 2 at its fifth quad; face z = 10 between cells (69, 69, 9) and
// (69, 69, 10), the positions as the kernel made them): quad 3's rim line
// (planes 301, 303 here) pokes 2.2e-5 mm through quad 4's offset face
// (403), so the face's section runs along 403's line to A, out to the tip
// C and back to B, A and B 9e-7 mm apart and one float point once written.
// Below, the two triangles at C share the apex I and lie on each other
// written (and the cone's other triangles meet them where A and B do);
// above, their two apexes keep them apart but for that point. Both cells
// merge B into A: below, the two triangles then coincide facing opposite
// ways and go with C; above, C's two edges are one edge used both ways.
// The seam stays; nothing crosses.
TEST(FloatFolds, ASpikeOfAFacesSectionWhoseBaseRoundsToOnePointIsClosedInBothCells)
{
    const openvdb::Vec3d origin(0.0), spacing(1.0);
    const Coord lo(69, 69, 9), hi(69, 69, 10);
    const Coord f0(69, 69, 10), f1(69, 70, 10), f2(70, 70, 10); // a tet face in z = 10
    const CutVertexId A = faceVertex(f0, f1, f2, 301, 403), B = faceVertex(f0, f1, f2, 303, 403),
                      C = faceVertex(f0, f1, f2, 301, 303);
    const CutVertexId P1 = faceVertex(f0, f1, f2, 403, 500), P2 = faceVertex(f0, f1, f2, 403, 501),
                      Q = faceVertex(f0, f1, f2, 500, 501);
    const dvec3 atA(69.363578927312, 69.472530621625, 10.0), atB(69.363579780012, 69.472530912011, 10.0),
        atC(69.363579725147, 69.472552351740, 10.0), atP1(69.294747703859, 69.449090221756, 10.0),
        atP2(69.528794665312, 69.528794665312, 10.0), atQ(69.45, 69.35, 10.0);
    auto cell = [&](bool below) {
        Builder b;
        const uint32_t a = b.add(A, atA), bb = b.add(B, atB), c = b.add(C, atC), p1 = b.add(P1, atP1),
                       p2 = b.add(P2, atP2), q = b.add(Q, atQ);
        if (below) { // a cone from I over the section P2, B, C, A, P1, Q
            const uint32_t i = b.add(innerVertex(lo, 3, 403), {69.333599328304, 69.426568763327, 9.943579951057});
            b.tri(p2, bb, i);
            b.tri(bb, c, i);
            b.tri(c, a, i);
            b.tri(a, p1, i);
            b.tri(p1, q, i);
            b.tri(q, p2, i);
        } else { // the section the other way round, under two apexes
            const uint32_t k1 = b.add(innerVertex(hi, 1, 301), {69.36, 69.42, 10.02});
            const uint32_t k2 = b.add(innerVertex(hi, 1, 303), {69.44, 69.43, 10.02});
            b.tri(a, c, k1);
            b.tri(c, k2, k1);
            b.tri(c, bb, k2);
            b.tri(bb, p2, k2);
            b.tri(p2, q, k2);
            b.tri(k2, q, k1);
            b.tri(q, p1, k1);
            b.tri(p1, a, k1);
        }
        return b.g;
    };
    // Pairs of the cell's triangles that cross or touch once written (as the
    // local check judges a cut with a width, names as vertex ids).
    auto crossings = [](const CutCellGeometry& g) {
        std::map<CutVertexId, uint32_t> number;
        for (const CutVertexId& id : g.vertexIds) number.emplace(id, uint32_t(number.size()));
        size_t n = 0;
        for (size_t s = 0; s + 2 < g.indices.size(); s += 3)
            for (size_t t = s + 3; t + 2 < g.indices.size(); t += 3) {
                std::array<glm::vec3, 3> ps, pt;
                std::array<uint32_t, 3> is, it;
                for (size_t k = 0; k < 3; ++k) {
                    ps[k] = glm::vec3(g.indexPositions[g.indices[s + k]]);
                    pt[k] = glm::vec3(g.indexPositions[g.indices[t + k]]);
                    is[k] = number[g.vertexIds[g.indices[s + k]]];
                    it[k] = number[g.vertexIds[g.indices[t + k]]];
                }
                n += mtcut::cutter::trianglesCross(ps, is, pt, it) != mtcut::cutter::Contact::None;
            }
        return n;
    };
    auto seam = [](const CutCellGeometry& below, const CutCellGeometry& above) {
        const auto b = boundary(below), a = boundary(above);
        if (b.size() != a.size() || b.empty()) return false;
        for (const KeyEdge& e : b)
            if (!a.count({e.second, e.first})) return false;
        return true;
    };
    CutCellGeometry below = cell(true), above = cell(false);
    // The premise: the cells weld, A and B are one float point, the two
    // triangles at C below lie on each other once written, and above none do.
    ASSERT_TRUE(seam(below, above));
    ASSERT_EQ(glm::vec3(atA), glm::vec3(atB));
    ASSERT_EQ(crossings(below), 4u); // the pair at C, and each side of the cone once A and B meet
    ASSERT_EQ(crossings(above), 1u); // the triangles at C, which meet where A and B do
    // In every cell the kernel makes (not only once the local check has
    // failed: a cell kept from an earlier update and one made now must agree).
    EXPECT_EQ(repairFloatFolds(lo, origin, spacing, below), 1u);
    EXPECT_EQ(repairFloatFolds(hi, origin, spacing, above), 1u);
    EXPECT_EQ(below.indices.size(), 12u) << "the two triangles at the tip go";
    EXPECT_EQ(above.indices.size(), 24u);
    for (const CutCellGeometry* g : {&below, &above}) {
        EXPECT_EQ(std::count(g->vertexIds.begin(), g->vertexIds.end(), B), 0) << "B is A now";
        EXPECT_EQ(std::count(g->vertexIds.begin(), g->vertexIds.end(), A), 1);
        EXPECT_EQ(crossings(*g), 0u);
    }
    EXPECT_EQ(std::count(below.vertexIds.begin(), below.vertexIds.end(), C), 0) << "the tip goes below";
    EXPECT_EQ(std::count(above.vertexIds.begin(), above.vertexIds.end(), C), 1) << "and stays above";
    EXPECT_TRUE(seam(below, above)) << "the cells of the face judged the spike differently";
    // A base float keeps apart is no spike: the same section with B moved
    // 1e-4 mm along 403's line is left as it is.
    for (const bool lower : {true, false}) {
        CutCellGeometry wide = cell(lower);
        wide.indexPositions[1] = atA + 1e-4 / glm::length(atP2 - atP1) * (atP2 - atP1);
        EXPECT_EQ(repairFloatFolds(lower ? lo : hi, origin, spacing, wide, true), 0u);
    }
}

// Snap rounding's rule for an edge along a grid edge used four times
// (fusedMesh and the local check; tooth at 400, kerf 0.5, seed 9076: a blade
// plane 6e-6 mm from the isosurface's vertex on a grid edge, the sliver of
// solid round the edge pinched by the face rule in two opposite faces):
// only from the edge's iso vertex to a blade-only, untagged vertex of the
// same grid edge, within two float steps at the edge's largest coordinate.
TEST(FloatFolds, OnlyAnIsoVertexAndABladeVertexOfItsGridEdgeAFloatStepApartJoinAlongIt)
{
    using mtcut::cutter::remesh_detail::joinsAlongGridEdge;
    const openvdb::Vec3d origin(1000.0), spacing(1.0);
    const Coord a(1, 1, 1), b(2, 1, 1), c(1, 2, 1);
    const CutVertexId iso = edgeVertex(a, b, 1), blade = edgeVertex(a, b, 200);
    const glm::vec3 x(1001.5f, 1001.0f, 1001.0f);
    // Floats at 1001.5 are 6.1e-5 mm apart; the reach, 2 epsilon x 1002 mm, is 2.4e-4 mm.
    glm::vec3 oneStep = x, fiveSteps = x;
    oneStep.x = std::nextafter(x.x, 2000.0f);
    for (int i = 0; i < 5; ++i) fiveSteps.x = std::nextafter(fiveSteps.x, 2000.0f);
    EXPECT_TRUE(joinsAlongGridEdge(iso, blade, x, oneStep, origin, spacing));
    EXPECT_FALSE(joinsAlongGridEdge(iso, blade, x, fiveSteps, origin, spacing)) << "beyond the reach";
    EXPECT_FALSE(joinsAlongGridEdge(blade, iso, oneStep, x, origin, spacing)) << "the first must be the iso vertex";
    EXPECT_FALSE(joinsAlongGridEdge(iso, edgeVertex(a, c, 200), x, oneStep, origin, spacing)) << "another grid edge";
    CutVertexId tagged = blade;
    tagged.tags[tagged.tagCount++] = 200u << 1;
    EXPECT_FALSE(joinsAlongGridEdge(iso, tagged, x, oneStep, origin, spacing)) << "a side or pinch copy";
    CutVertexId isoOnPlane = blade; // an iso vertex on a blade plane: {1, 200}
    isoOnPlane.planeCount = 2;
    isoOnPlane.planes = {1, 200};
    EXPECT_FALSE(joinsAlongGridEdge(iso, isoOnPlane, x, oneStep, origin, spacing)) << "an iso vertex on a plane";
    // Near the origin a float step is smaller, and so is the reach.
    const glm::vec3 y(1.5f, 1.0f, 1.0f);
    EXPECT_FALSE(joinsAlongGridEdge(iso, blade, y, y + glm::vec3(1e-6f, 0, 0), openvdb::Vec3d(0.0), spacing));
}

// Snap rounding's rule for an edge inside a tet face used four times (1 mm
// head at 400, kerf 0.5, seed 9355: a prism's corner line meets the
// isosurface a float step below face z = 1209 mm; the notch's vertices
// round into the face or collapse in both cells, whose iso and cap
// triangles then meet along the iso line's segment between the two sides,
// 3.4e-4 mm long): only an untagged vertex inside a tet face and another of
// the closed face (inside it with a lower name, or on an edge of it), kept
// first, within four float steps at the face's largest coordinate.
TEST(FloatFolds, OnlyTwoVerticesOfATetFaceAFewFloatStepsApartJoinAtAPinch)
{
    using mtcut::cutter::remesh_detail::joinsPinchInFace;
    const openvdb::Vec3d origin(1000.0), spacing(1.0);
    const Coord f0(1, 1, 1), f1(2, 1, 1), f2(1, 2, 1);
    CutVertexId a = faceVertex(f0, f1, f2, 1, 200), b = faceVertex(f0, f1, f2, 1, 201);
    if (b < a) std::swap(a, b);
    // Floats at 1001.5 are 6.1e-5 mm apart; the reach, 4 epsilon x 1002 mm
    // (the face's largest coordinate), is 4.8e-4 mm.
    const glm::vec3 x(1001.5f, 1001.25f, 1001.0f);
    EXPECT_TRUE(joinsPinchInFace(a, b, x, x + glm::vec3(3.4e-4f, 0, 0), origin, spacing));
    EXPECT_FALSE(joinsPinchInFace(a, b, x, x + glm::vec3(6e-4f, 0, 0), origin, spacing)) << "beyond the reach";
    EXPECT_FALSE(joinsPinchInFace(b, a, x, x + glm::vec3(1e-4f, 0, 0), origin, spacing)) << "the lower name first";
    EXPECT_FALSE(joinsPinchInFace(a, faceVertex(f0, f1, Coord(2, 2, 1), 1, 201), x, x, origin, spacing))
        << "another tet face";
    EXPECT_FALSE(joinsPinchInFace(a, edgeVertex(f0, f1, 201), x, x, origin, spacing)) << "the face's vertex is the other";
    // A vertex of an edge of the face is kept (tooth, seed 9273: an offset
    // plane 8e-6 mm beside the isosurface's vertex on a face diagonal).
    const CutVertexId onEdge = edgeVertex(f1, f2, 1);
    EXPECT_TRUE(joinsPinchInFace(onEdge, b, x, x + glm::vec3(1e-5f, 0, 0), origin, spacing));
    EXPECT_FALSE(joinsPinchInFace(edgeVertex(f1, Coord(2, 2, 1), 1), b, x, x, origin, spacing))
        << "an edge of another face";
    CutVertexId tagged = b;
    tagged.tags[tagged.tagCount++] = 201u << 1;
    EXPECT_FALSE(joinsPinchInFace(a, tagged, x, x, origin, spacing)) << "a side or pinch copy";
    // Near the origin a float step is smaller, and so is the reach.
    const glm::vec3 y(1.5f, 1.25f, 1.0f);
    EXPECT_FALSE(joinsPinchInFace(a, b, y, y + glm::vec3(2e-6f, 0, 0), openvdb::Vec3d(0.0), spacing));
    EXPECT_TRUE(joinsPinchInFace(a, b, y, y + glm::vec3(4e-7f, 0, 0), openvdb::Vec3d(0.0), spacing));
}

// Snap rounding's rule for two vertices of faces round a cube edge (1 mm
// head at 400, kerf 0.5, seed 9065: the isosurface's line on a kerf plane
// crossing faces z = 1053 and x = 212 1.6e-5 mm apart beside their edge):
// the same planes, untagged, in faces of two axes that share the edge, both
// rounded to within two float steps of the edge's line and of each other.
TEST(FloatFolds, OnlyVerticesOfTwoFacesRoundACubeEdgeRoundedOntoItAFloatStepApartJoin)
{
    using mtcut::cutter::remesh_detail::facesMeetAtCubeEdge;
    using mtcut::cutter::remesh_detail::joinsRoundCubeEdge;
    const openvdb::Vec3d origin(1000.0), spacing(1.0);
    // The cube edge (1, 1..2, 1); face z = 1 and face x = 1 (their tet faces' grid vertices).
    const Coord e0(1, 1, 1), e1(1, 2, 1);
    const CutVertexId inZ = faceVertex(e0, Coord(2, 1, 1), e1, 1, 300);
    const CutVertexId inX = faceVertex(e0, e1, Coord(1, 1, 2), 1, 300);
    ASSERT_TRUE(facesMeetAtCubeEdge(inZ, inX));
    ASSERT_TRUE(facesMeetAtCubeEdge(inX, inZ));
    const glm::vec3 a(1001.0f, 1001.5f, 1001.0f);
    glm::vec3 oneStep = a, fiveSteps = a;
    oneStep.y = std::nextafter(a.y, 2000.0f);
    for (int i = 0; i < 5; ++i) fiveSteps.y = std::nextafter(fiveSteps.y, 2000.0f);
    EXPECT_TRUE(joinsRoundCubeEdge(inZ, inX, a, oneStep, origin, spacing));
    EXPECT_TRUE(joinsRoundCubeEdge(inZ, inX, a, a, origin, spacing));
    EXPECT_FALSE(joinsRoundCubeEdge(inZ, inX, a, fiveSteps, origin, spacing)) << "beyond the reach";
    // One float step off the edge's line is within the reach (1 mm head, seed
    // 9239: y one step below 249 mm in face z = 1125); five are not.
    glm::vec3 offLine = oneStep, farOff = oneStep;
    offLine.x = std::nextafter(offLine.x, 2000.0f);
    for (int i = 0; i < 5; ++i) farOff.x = std::nextafter(farOff.x, 2000.0f);
    EXPECT_TRUE(joinsRoundCubeEdge(inZ, inX, a, offLine, origin, spacing));
    EXPECT_FALSE(joinsRoundCubeEdge(inZ, inX, a, farOff, origin, spacing)) << "one is off the edge's line";
    farOff = a;
    for (int i = 0; i < 5; ++i) farOff.z = std::nextafter(farOff.z, 0.0f);
    EXPECT_FALSE(joinsRoundCubeEdge(inZ, inX, farOff, a, origin, spacing)) << "one is off the edge's line";
    // Other planes, a tag, one face, opposite faces, faces meeting at a point only.
    EXPECT_FALSE(facesMeetAtCubeEdge(inZ, faceVertex(e0, e1, Coord(1, 1, 2), 1, 301))) << "another line";
    CutVertexId tagged = inX;
    tagged.tags[tagged.tagCount++] = 300u << 1;
    EXPECT_FALSE(facesMeetAtCubeEdge(inZ, tagged)) << "a side or pinch copy";
    EXPECT_FALSE(facesMeetAtCubeEdge(inZ, inZ)) << "one vertex";
    EXPECT_FALSE(facesMeetAtCubeEdge(inZ, faceVertex(Coord(2, 2, 1), Coord(2, 1, 1), e1, 1, 300)))
        << "the other tet face of the same cell face";
    EXPECT_FALSE(facesMeetAtCubeEdge(inZ, faceVertex(e0, Coord(1, 0, 1), Coord(1, 1, 0), 1, 300))) << "a point in common";
    // Face y = 1 meets face z = 1 at another cube edge, (1..2, 1, 1): inZ on it is off that line.
    const CutVertexId inY = faceVertex(e0, Coord(2, 1, 1), Coord(2, 1, 2), 1, 300);
    EXPECT_TRUE(facesMeetAtCubeEdge(inZ, inY));
    EXPECT_FALSE(joinsRoundCubeEdge(inZ, inY, a, a, origin, spacing)) << "off that edge's line";
    EXPECT_FALSE(facesMeetAtCubeEdge(inZ, faceVertex(e0, e1, Coord(2, 1, 2), 1, 300))) << "an inner tet face";
    EXPECT_FALSE(facesMeetAtCubeEdge(edgeVertex(e0, e1, 300), inX)) << "a vertex of the edge itself";
}

// remesh_detail::linkFans, on which the split of pinches across cells
// (CutRemesher::fusedMesh, kerf > 0) and the local check rely: a vertex's
// link that is one cycle is one fan; two disjoint cycles are two fans, each
// edge numbered by its cycle in order of first edge; anything else (an open
// link, a link vertex starting two edges, two cycles sharing a vertex, a
// cycle of two edges: two triangles back to back) is 0.
// Tooth, kerf 0.5, random strokes seed 9127: in cell (78, 24, 160) a vertex
// inside tet 0, 3e-6 mm above the face z = 160 (a float step there is
// 1.5e-5), rounded into the face; its triangle with two vertices of the face
// then lay in the face, and the cell below's triangle with an edge in the
// face ran through it. Such a private vertex is put one float step inside
// its cell; a tent's apex (every neighbour in the face) and vertices that
// round inside are left as they are.
TEST(FloatFolds, APrivateVertexRoundedIntoItsCellsFaceIsPutAFloatStepInside)
{
    const Coord cell(78, 24, 160);
    Builder b;
    // The face z = 160 (the cell's lower face), a tet face in it and its edge x = 79.
    const uint32_t F = b.add(faceVertex({78, 24, 160}, {79, 24, 160}, {79, 25, 160}, 1, 7),
                             {78.999031, 24.166344, 160.0});
    const uint32_t E = b.add(edgeVertex({79, 24, 160}, {79, 25, 160}, 1), {79.0, 24.166666, 160.0});
    const uint32_t G = b.add(faceVertex({78, 24, 160}, {78, 25, 160}, {79, 25, 160}, 1, 7), {78.4, 24.9, 160.0});
    const uint32_t H = b.add(faceVertex({78, 24, 160}, {78, 24, 161}, {79, 24, 161}, 1, 7), {78.7, 24.0, 160.6});
    const uint32_t V = b.add(innerVertex(cell, 0, 7), {78.999092, 24.166515, 160.0 + 3e-6}); // rounds into z = 160
    const uint32_t T = b.add(innerVertex(cell, 1, 8), {78.6, 24.5, 160.0 + 2e-6});           // a tent's apex
    const uint32_t U = b.add(innerVertex(cell, 2, 9), {78.5, 24.5, 161.0 - 3e-6});           // rounds into z = 161
    const uint32_t W = b.add(innerVertex(cell, 3, 9), {78.5, 24.5, 160.0 + 3e-4});           // rounds inside
    // A centre S of a strip thinner than a float step (P and Q 1e-5 mm above
    // the face, written one float step above it): lifted, S would lie on the
    // line P Q once written, so it is left to the float repair.
    const uint32_t S = b.add(innerVertex(cell, 4, 10), {78.5, 24.2, 160.0 + 3e-6});
    const uint32_t P = b.add(innerVertex(cell, 4, 11), {78.2, 24.2, 160.0 + 1e-5});
    const uint32_t Q = b.add(innerVertex(cell, 4, 12), {78.8, 24.2, 160.0 + 1e-5});
    b.tri(F, E, V);
    b.tri(V, E, H);
    b.tri(F, V, H);
    b.tri(F, G, T);
    b.tri(G, E, T);
    b.tri(E, F, T);
    b.tri(U, H, W);
    b.tri(W, H, G);
    b.tri(S, P, Q);
    CutCellGeometry g = b.g;
    const dvec3 origin(0.0), spacing(1.0);
    auto lift = [](const Coord& c, const dvec3& o, const dvec3& s, CutCellGeometry& x) {
        return liftOffCellFaces(c, openvdb::Vec3d(o.x, o.y, o.z), openvdb::Vec3d(s.x, s.y, s.z), x);
    };
    auto written = [&](uint32_t v, int axis) { return float(origin[axis] + spacing[axis] * g.indexPositions[v][axis]); };
    ASSERT_EQ(written(V, 2), 160.0f);
    ASSERT_EQ(written(T, 2), 160.0f);
    ASSERT_EQ(written(U, 2), 161.0f);
    ASSERT_NE(written(W, 2), 160.0f);
    ASSERT_EQ(written(S, 2), 160.0f);
    ASSERT_EQ(written(P, 2), std::nextafter(160.0f, 161.0f));
    EXPECT_EQ(lift(cell, origin, spacing, g), 2u);
    EXPECT_EQ(written(V, 2), std::nextafter(160.0f, 161.0f));
    EXPECT_EQ(written(U, 2), std::nextafter(161.0f, 160.0f));
    EXPECT_GT(g.indexPositions[V].z, 160.0);
    EXPECT_LT(g.indexPositions[U].z, 161.0);
    for (uint32_t v : {V, U}) // only the coordinate that rounded into the face moved
        for (int axis : {0, 1}) EXPECT_EQ(g.indexPositions[v][axis], b.g.indexPositions[v][axis]);
    for (uint32_t v : {F, E, G, H, T, W, S, P, Q}) EXPECT_EQ(g.indexPositions[v], b.g.indexPositions[v]);
    EXPECT_EQ(lift(cell, origin, spacing, g), 0u); // nothing left to lift
    // The same in a grid whose origin and spacing are not 0 and 1 (the scan's mm).
    CutCellGeometry h = b.g;
    const dvec3 origin2(-12.25, 3.5, 1002.0), spacing2(0.5, 0.5, 0.625);
    h.indexPositions[V].z = h.indexPositions[T].z = 160.0 + 1e-6 / spacing2.z;
    // Here a float step is 1.2e-4 mm: P and Q round into the face too, and
    // go up with V and U; S, below them, would then fold and stays.
    EXPECT_EQ(lift(cell, origin2, spacing2, h), 4u);
    EXPECT_EQ(h.indexPositions[S], b.g.indexPositions[S]);
    const float low = float(origin2.z + spacing2.z * 160.0), high = float(origin2.z + spacing2.z * 161.0);
    EXPECT_EQ(float(origin2.z + spacing2.z * h.indexPositions[V].z), std::nextafter(low, high));
    EXPECT_EQ(float(origin2.z + spacing2.z * h.indexPositions[U].z), std::nextafter(high, low));
    EXPECT_EQ(h.indexPositions[T].z, 160.0 + 1e-6 / spacing2.z);
}

// Two prisms of a blade that pivots on a corner meet in a cell face: a
// vertex of one's section of the face lies 1.25e-5 mm beside an edge of the
// other's, and rounded to float (a step is 1.2e-4 mm at z = 1061 mm) it
// lands on that edge, so the triangles at it and at the edge cross once
// written (2 mm head at -300, kerf 0.5, random strokes seed 9037). Both
// cells of the face put it a float step over, to the side it is on.
TEST(FloatFolds, AFaceVertexRoundedAcrossAnEdgeOfTheFaceIsPutBackInBothCells)
{
    const openvdb::Vec3d origin(0.0, 0.0, 1000.0), spacing(1.0);
    const Coord below(0, 0, 60), above(0, 1, 60); // the face y = 1 between them
    // A tet face in y = 1; the edge A B on the line z = 1000 + x + 60.
    auto face = [](uint64_t p0, uint64_t p1) { return faceVertex({0, 1, 60}, {1, 1, 60}, {1, 1, 61}, p0, p1); };
    const CutVertexId a = face(0x1000000002, 0x1000000008), bId = face(0x1000000002, 0x1000000003);
    const CutVertexId p = face(0x1000000022, 0x1000000023), c = face(0x1000000022, 0x1000000028);
    const CutVertexId iso = edgeVertex({1, 1, 60}, {1, 1, 61}, 1); // the isosurface's: never moved
    const dvec3 atA(0.25, 1.0, 60.25), atB(0.75, 1.0, 60.75);
    const dvec3 atP(0.5, 1.0, 60.5 - 1.25e-5); // below the line; written on it
    const dvec3 atC(0.9, 1.0, 60.1), atIso(1.0, 1.0, 60.5);
    auto cellOf = [&](const Coord& cell) {
        Builder b;
        const uint32_t A = b.add(a, atA), B = b.add(bId, atB), P = b.add(p, atP), C = b.add(c, atC);
        const uint32_t I = b.add(iso, atIso);
        const uint32_t X = b.add(innerVertex(cell, 0, 9), {0.5, cell.y() + 0.5, 60.5});
        // A B and P C lie in the face: edges of the face's section, which
        // both cells' triangles use (each the other way round).
        if (cell == below) {
            b.tri(A, B, X);
            b.tri(P, C, X);
            b.tri(C, I, X);
        } else {
            b.tri(B, A, X);
            b.tri(C, P, X);
            b.tri(I, C, X);
        }
        return b.g;
    };
    auto writtenOf = [&](const dvec3& x) {
        return glm::vec3(float(origin.x() + x.x), float(origin.y() + x.y), float(origin.z() + x.z));
    };
    // In the face (z, x): exactly below the line, written on it.
    using mtcut::cutter::orient2d;
    using mtcut::cutter::Sign;
    const glm::vec3 wA = writtenOf(atA), wB = writtenOf(atB);
    ASSERT_EQ(orient2d(wA, wB, writtenOf(atP), 2, 0), Sign::Zero);
    const Sign exactSide = orient2d(glm::vec3(atA), glm::vec3(atB), glm::vec3(0.5f, 1.0f, 60.4f), 2, 0);
    ASSERT_NE(exactSide, Sign::Zero);
    CutCellGeometry lo = cellOf(below), hi = cellOf(above);
    EXPECT_EQ(keepFaceSidesOnceWritten(below, origin, spacing, lo), 1u);
    EXPECT_EQ(keepFaceSidesOnceWritten(above, origin, spacing, hi), 1u);
    const uint32_t P = 2;
    EXPECT_EQ(lo.indexPositions[P], hi.indexPositions[P]) << "both cells of the face move it alike";
    const glm::vec3 wP = writtenOf(lo.indexPositions[P]);
    EXPECT_EQ(orient2d(wA, wB, wP, 2, 0), exactSide);
    EXPECT_EQ(wP.y, 1.0f) << "it stays in the face";
    EXPECT_LE(std::abs(double(wP.z) - double(writtenOf(atP).z)), 1.3e-4) << "a float step at most";
    EXPECT_LE(std::abs(double(wP.x) - double(writtenOf(atP).x)), 1e-7);
    for (uint32_t v : {0u, 1u, 3u, 4u, 5u}) EXPECT_EQ(lo.indexPositions[v], cellOf(below).indexPositions[v]) << v;
    EXPECT_EQ(keepFaceSidesOnceWritten(below, origin, spacing, lo), 0u) << "nothing left";
    // Left alone: the same vertex 3e-4 mm below the line (written below
    // it), and one exactly on the line (on it, written on it).
    for (double off : {3e-4, 0.0}) {
        CutCellGeometry g = cellOf(below);
        g.indexPositions[P].z = 60.5 - off;
        const dvec3 before = g.indexPositions[P];
        EXPECT_EQ(keepFaceSidesOnceWritten(below, origin, spacing, g), 0u) << off;
        EXPECT_EQ(g.indexPositions[P], before) << off;
    }
}

// An offset plane (k) nearly parallel to the isosurface crosses the face
// diagonal (48,147,25)-(49,147,26) of cell (48,146,25) 2e-3 voxel from the
// isosurface's vertex I there (at K), and their line passes within 3e-4
// voxel of the diagonal: the wedge of solid between them round K and I
// (0.45 x 0.45 x 1.25 mm voxels, the skin at -300, kerf 0.5, random strokes
// seed 11033, the cell's triangles as the kernel made them). The short edge
// from X, a vertex of an inner tet face, to K is the shortest; collapsing
// X onto K joined K and I, both on the face's diagonal, by an edge, and
// the cell across the face did the same with a vertex of its own: the
// edge used twice each way, which the local check refused. Such a collapse
// is not made; the repair mends the cell without an edge in a cell face
// that it did not have.
TEST(FloatFolds, ACollapseMakesNoNewEdgeInACellFace)
{
    const Coord cell(48, 146, 25);
    const openvdb::Vec3d origin(74.0, 134.0, 1000.0), spacing(0.45, 0.45, 1.25);
    const uint64_t k = mtcut::cutter::remesh_detail::planeIdOf(2, 16, 9); // quad 16's offset plane
    const Coord o(48, 147, 25), d(49, 147, 26); // the diagonal
    Builder b;
    const uint32_t E = b.add(edgeVertex(o, {48, 147, 26}, 1), {48.0, 147.0, 25.428571428571});
    const uint32_t Xf = b.add(faceVertex(o, {48, 146, 26}, {48, 147, 26}, 1, k), {48.0, 146.985004719118, 25.220779679203});
    const uint32_t Ke = b.add(edgeVertex(o, {48, 147, 26}, k), {48.0, 147.0, 25.219484326986});
    const uint32_t I = b.add(edgeVertex(o, d, 1), {48.206896551724, 147.0, 25.206896551724});
    const uint32_t K = b.add(edgeVertex(o, d, k), {48.205355939267, 147.0, 25.205355939267});
    const uint32_t Xy = b.add(faceVertex(o, {49, 147, 25}, d, 1, k), {48.206955503928, 147.0, 25.205245890004});
    const uint32_t X7 = b.add(faceVertex({49, 146, 25}, o, d, 1, k), {48.205594355428, 146.999765442903, 25.205359798331});
    const uint32_t X = b.add(faceVertex(o, {48, 146, 26}, d, 1, k), {48.205147486250, 146.999756139910, 25.205391346340});
    b.tri(E, Xf, I); // the isosurface
    b.tri(Xf, X, I);
    b.tri(X7, I, X);
    b.tri(Xy, I, X7);
    b.tri(Xf, Ke, X); // the offset plane
    b.tri(Ke, K, X);
    b.tri(X, K, X7);
    b.tri(K, Xy, X7);
    CutCellGeometry g = b.g;
    const auto edgesBefore = directedEdges(g);
    const auto before = boundary(g);
    auto inOneFace = [&](const CutVertexId& v, const CutVertexId& w) { // both on one of the cell's six faces
        auto on = [&](const CutVertexId& id, int axis, int at) {
            if (id.dim == 3) return false;
            for (int f = 0; f <= id.dim; ++f)
                if (mtcut::cutter::gridVertexCoord(id.feature[size_t(f)])[axis] != at) return false;
            return true;
        };
        for (int axis = 0; axis < 3; ++axis)
            for (int at : {cell[axis], cell[axis] + 1})
                if (on(v, axis, at) && on(w, axis, at)) return true;
        return false;
    };
    EXPECT_GE(repairFloatFolds(cell, origin, spacing, g), 1u);
    const dvec3 o3(origin.x(), origin.y(), origin.z()), s3(spacing.x(), spacing.y(), spacing.z());
    EXPECT_EQ(foldedInFloat(g, o3, s3), 0u);
    EXPECT_EQ(boundary(g), before);
    for (const auto& [edge, n] : directedEdges(g)) {
        if (!inOneFace(edge.first, edge.second)) continue;
        EXPECT_TRUE(edgesBefore.count(edge)) << "a new edge in a cell face";
    }
    // The premise: the edge the collapse onto K would make lies in face y = 147.
    EXPECT_TRUE(inOneFace(b.g.vertexIds[K], b.g.vertexIds[I]));
    EXPECT_FALSE(edgesBefore.count({b.g.vertexIds[K], b.g.vertexIds[I]}));
}

// A stroke folding back and forth: three end planes (quads 41, 42 and 43)
// cross the tet face (84,32,88)-(85,32,88)-(85,32,89), in cell face y = 32,
// within 2e-5 voxel of each other, and two of them the cell's edge below it
// 4.5e-6 voxel apart (0.45 x 0.45 x 1.25 mm voxels, the skin at -300, kerf
// 0.5, random strokes seed 11042, stroke 0 at quad 43; cell (84, 31, 88)'s
// triangles there as the kernel made them). B and A, the ends of a short
// edge inside the face, have the cell edge's vertex E as a common
// neighbour, so the link condition fails; but the edge B-E is used both
// ways in this cell (by a triangle of its own lying in the face), so the
// cell across (84, 32, 88) has no such edge, saw no triangle A-B-E of the
// face's section, and merged B into A. This cell kept them apart, and the
// seam opened (an edge used twice one way). It now merges them too: the
// two triangles at E that then coincide facing opposite ways go, with the
// vertex inside the tet, and the triangle in the face is left.
TEST(FloatFolds, AFaceRuleCollapseThroughATriangleInTheFaceIsMadeAsAcrossTheFace)
{
    using mtcut::cutter::remesh_detail::planeIdOf;
    const Coord cell(84, 31, 88);
    const openvdb::Vec3d origin(74.0, 134.0, 1000.0), spacing(0.45, 0.45, 1.25);
    const Coord a(84, 32, 88), b(85, 32, 88), c(85, 32, 89); // the tet face in cell face y = 32
    const uint64_t end41 = planeIdOf(1, 41, 4), end42 = planeIdOf(1, 42, 3), end43 = planeIdOf(1, 43, 2);
    Builder bld;
    const uint32_t E = bld.add(edgeVertex(a, b, end41), {84.581296901340, 32.0, 88.0});
    const uint32_t F = bld.add(edgeVertex(a, b, end43), {84.581292364396, 32.0, 88.0});
    const uint32_t A = bld.add(faceVertex(a, b, c, end41, end42), {84.584712885236, 32.0, 88.001898492464});
    const uint32_t B = bld.add(faceVertex(a, b, c, end42, end43), {84.584696763393, 32.0, 88.001907217763});
    CutVertexId inner;
    inner.dim = 3;
    inner.feature = {gridVertexId(cell.x(), cell.y(), cell.z()), 1, 0};
    inner.planeCount = 6;
    inner.planes = {planeIdOf(1, 41, 1), end41, planeIdOf(1, 42, 1), end42, planeIdOf(1, 43, 1), end43, 0, 0};
    const uint32_t T = bld.add(inner, {84.584584610685, 31.998363065031, 88.001807599273});
    bld.tri(E, A, T);
    bld.tri(A, B, T);
    bld.tri(B, E, T);
    bld.tri(B, F, E); // in the face
    ASSERT_LT(bld.g.vertexIds[A], bld.g.vertexIds[B]);
    CutCellGeometry g = bld.g;
    EXPECT_GE(repairFloatFolds(cell, origin, spacing, g), 1u);
    ASSERT_EQ(g.indices.size(), 3u) << "the triangle in the face alone";
    std::vector<CutVertexId> left;
    for (uint32_t v : g.indices) left.push_back(g.vertexIds[v]);
    std::rotate(left.begin(), std::min_element(left.begin(), left.end()), left.end());
    const std::vector<CutVertexId> want = {bld.g.vertexIds[E], bld.g.vertexIds[A], bld.g.vertexIds[F]};
    std::vector<CutVertexId> wantRotated = want;
    std::rotate(wantRotated.begin(), std::min_element(wantRotated.begin(), wantRotated.end()), wantRotated.end());
    EXPECT_TRUE(left == wantRotated) << "B became A, facing as (B, F, E) did";
    // The boundary: E -> A -> B -> F -> E before; E -> A -> F -> E now,
    // what the cell across meets once it has merged B into A too.
    const auto after = boundary(g);
    EXPECT_EQ(after.size(), 3u);
    EXPECT_TRUE(after.count({bld.g.vertexIds[E], bld.g.vertexIds[A]}));
    EXPECT_TRUE(after.count({bld.g.vertexIds[A], bld.g.vertexIds[F]}));
    EXPECT_TRUE(after.count({bld.g.vertexIds[F], bld.g.vertexIds[E]}));
}

// An offset plane crosses grid edge E = (92,145,21)-(92,145,22) 2.3e-3 mm
// from the isosurface's vertex I there (its own vertex P), and the line
// where the two meet crosses cell face x = 92 at F, a float step and a half
// from P (0.8 x 0.8 x 2.4 mm voxels, the skin at -300, kerf 0.5, random
// strokes seed 10023, stroke 3 at quad 17; cell (91, 144, 21)'s tet at E as
// the kernel made it). The face rule merged F into P, which turned the
// isosurface's triangle I-X-F into I-X-P: an edge along E, which the cell
// did not have. Each of the four cells round E did the same in one of its
// two faces there, and the edge was used twice each way. The face rule now
// makes no new edge along a cube edge, so F stays (both cells of the face
// decide alike: the face's section I-F-P is theirs alike).
TEST(FloatFolds, TheFaceRuleMakesNoNewEdgeAlongACubeEdge)
{
    using mtcut::cutter::remesh_detail::planeIdOf;
    const Coord cell(91, 144, 21);
    const openvdb::Vec3d origin(74.0, 134.0, 1000.0), spacing(0.8, 0.8, 2.4);
    const uint64_t k = planeIdOf(4, 17, 9);
    const Coord e0(92, 145, 21), e1(92, 145, 22), f(92, 144, 22), in(91, 145, 22);
    Builder b;
    const uint32_t I = b.add(edgeVertex(e0, e1, 1), {92.0, 145.0, 21.380952380952});
    const uint32_t P = b.add(edgeVertex(e0, e1, k), {92.0, 145.0, 21.379988316722});
    const uint32_t F = b.add(faceVertex(e0, f, e1, 1, k), {92.0, 144.999788487326, 21.379925033678});
    const uint32_t X = b.add(faceVertex(e0, f, in, 1, k), {91.723393456807, 144.959696520123, 21.316910023070});
    const uint32_t J = b.add(edgeVertex(e0, in, 1), {91.272727272727, 145.0, 21.727272727273});
    const uint32_t Q = b.add(edgeVertex(e0, in, k), {91.679185569370, 145.0, 21.320814430630});
    b.tri(I, X, F); // the isosurface
    b.tri(I, J, X);
    b.tri(Q, P, X); // the offset plane
    b.tri(P, F, X);
    CutCellGeometry g = b.g;
    const auto before = directedEdges(g);
    repairFloatFolds(cell, origin, spacing, g);
    const auto after = directedEdges(g);
    EXPECT_FALSE(after.count({b.g.vertexIds[I], b.g.vertexIds[P]}) || after.count({b.g.vertexIds[P], b.g.vertexIds[I]}))
        << "an edge along the cube edge";
    for (const auto& [edge, n] : after) EXPECT_TRUE(before.count(edge)) << "a new edge";
    // The premise: F and P are a face rule pair (short by the face's reach).
    const double step = 1052.8 * double(std::numeric_limits<float>::epsilon());
    const dvec3 s3(spacing.x(), spacing.y(), spacing.z());
    EXPECT_LT(glm::length(s3 * (b.g.indexPositions[F] - b.g.indexPositions[P])), 2.0 * step);
}

TEST(LinkFans, CountsDisjointClosedCyclesAndNothingElse)
{
    using mtcut::cutter::remesh_detail::linkFans;
    std::vector<int> fan;
    EXPECT_EQ(linkFans({{1, 2}, {2, 3}, {3, 1}}, fan), 1);
    EXPECT_EQ(fan, (std::vector<int>{0, 0, 0}));
    EXPECT_EQ(linkFans({{1, 2}, {4, 5}, {2, 3}, {5, 6}, {6, 4}, {3, 1}}, fan), 2);
    EXPECT_EQ(fan, (std::vector<int>{0, 1, 0, 1, 1, 0}));
    EXPECT_EQ(linkFans({{1, 2}, {2, 3}, {3, 4}}, fan), 0);                          // open
    EXPECT_EQ(linkFans({{1, 2}, {2, 3}, {3, 1}, {1, 4}, {4, 5}, {5, 1}}, fan), 0);   // two cycles through 1
    EXPECT_EQ(linkFans({{1, 2}, {2, 1}, {1, 2}, {2, 1}}, fan), 0);                   // an edge used twice
    EXPECT_EQ(linkFans({{1, 2}, {2, 1}}, fan), 0);                                   // too short for a disc
    EXPECT_EQ(linkFans({{1, 2}, {2, 3}, {3, 1}, {4, 5}, {5, 4}}, fan), 0);          // and beside a disc
}

// remesh_detail::markCancellingPairs (fusedMesh and the local check): two
// triangles that snap rounding made into one vertex set facing opposite
// ways both go, and so do two such of which the float repair's face rule
// put one at least into a cell face; a pair that was one vertex set before
// snapping and that the repair did not make (the kernel's own, back to
// back) stays, and so do two facing the same way and a third on the set.
TEST(CancellingPairs, OnlyPairsMadeOnceWrittenGo)
{
    using mtcut::cutter::remesh_detail::markCancellingPairs;
    using T = std::array<uint32_t, 3>;
    using F = std::vector<char>;
    std::vector<char> drop;
    // A fan from centre 0 over corners 1, 2, 3 after 3 joined 2: (0, 1, 2) collapsed
    // elsewhere; (0, 2, 3) -> (0, 2, 2) collapsed; (0, 3, 1) -> (0, 2, 1) cancels (0, 1, 2).
    markCancellingPairs({T{0, 1, 2}, T{4, 5, 6}, T{0, 2, 1}}, {T{0, 1, 2}, T{4, 5, 6}, T{0, 3, 1}}, {}, drop);
    EXPECT_EQ(drop, (std::vector<char>{1, 0, 1}));
    // Rotations count as the same triangle; the pair is found across the list.
    markCancellingPairs({T{2, 0, 1}, T{7, 8, 9}, T{1, 0, 2}}, {T{2, 0, 1}, T{7, 8, 9}, T{1, 0, 3}}, {}, drop);
    EXPECT_EQ(drop, (std::vector<char>{1, 0, 1}));
    // The kernel's own back-to-back pair stays (the check refuses it).
    markCancellingPairs({T{0, 1, 2}, T{0, 2, 1}}, {T{0, 1, 2}, T{0, 2, 1}}, {}, drop);
    EXPECT_EQ(drop, (std::vector<char>{0, 0}));
    markCancellingPairs({T{0, 1, 2}, T{0, 2, 1}}, {T{0, 1, 2}, T{0, 2, 1}}, F{0, 0}, drop);
    EXPECT_EQ(drop, (std::vector<char>{0, 0}));
    // Two cells' triangles that the face rule put into their common face
    // (no snapping): both go, whether one or both are flagged.
    markCancellingPairs({T{4, 5, 6}, T{0, 1, 2}, T{0, 2, 1}}, {T{4, 5, 6}, T{0, 1, 2}, T{0, 2, 1}}, F{0, 1, 1}, drop);
    EXPECT_EQ(drop, (std::vector<char>{0, 1, 1}));
    markCancellingPairs({T{0, 1, 2}, T{1, 0, 2}}, {T{0, 1, 2}, T{1, 0, 2}}, F{0, 1}, drop);
    EXPECT_EQ(drop, (std::vector<char>{1, 1}));
    // ... but not two facing the same way.
    markCancellingPairs({T{0, 1, 2}, T{1, 2, 0}}, {T{0, 1, 2}, T{1, 2, 0}}, F{1, 1}, drop);
    EXPECT_EQ(drop, (std::vector<char>{0, 0}));
    // Facing the same way: no pair.
    markCancellingPairs({T{0, 1, 2}, T{1, 2, 0}}, {T{0, 1, 2}, T{1, 2, 3}}, {}, drop);
    EXPECT_EQ(drop, (std::vector<char>{0, 0}));
    // Three on one set: the first pair in triangle order goes, the third stays.
    markCancellingPairs({T{0, 1, 2}, T{0, 2, 1}, T{0, 1, 2}}, {T{0, 1, 2}, T{0, 2, 3}, T{0, 1, 4}}, {}, drop);
    EXPECT_EQ(drop, (std::vector<char>{1, 1, 0}));
    EXPECT_THROW(markCancellingPairs({T{0, 1, 2}}, {}, {}, drop), std::logic_error);
    EXPECT_THROW(markCancellingPairs({T{0, 1, 2}}, {T{0, 1, 2}}, F{0, 0}, drop), std::logic_error);
}
