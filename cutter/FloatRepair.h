// The float repair (DESIGN invariant 7 once written): what the re-meshing
// kernel's output needs so that it stays a clean 2-manifold once its vertices
// are rounded to float world mm, as fusedMesh() writes them. Each rule is a
// function of a cell's geometry (or of a vertex's name) and the grid's
// transform alone, so live, undone and from-scratch cuts mend alike. The
// kernel (RemeshKernel.cpp) runs snapToGridVertices, liftOffCellFaces,
// keepFaceSidesOnceWritten and repairFloatFolds on every cell it makes; the snap rounding rules
// (joinsAlongGridEdge, joinsPinchInFace, joinsRoundCubeEdge) are asked by fusedMesh() and the
// local check. Internal to cutter/; no GL.
#pragma once

#include "cutter/Remesh.h"

#include <glm/vec3.hpp>

#include <openvdb/math/Coord.h>
#include <openvdb/math/Vec3.h>

#include <cstddef>

namespace mtcut::cutter::remesh_detail {

using openvdb::Coord;

/// The float repair's reach: an edge shorter than kFloatStepsShort float
/// steps (float epsilon times the largest world coordinate, `extent` mm,
/// of the cell, face or grid edge that judges it) is mended (2 at the VHM
/// head's 1100 mm are 0.26 um: the least that mends test_cut_props'
/// strokes; 8 does too, moving more vertices further); snapToGridVertices
/// and joinsAlongGridEdge take the same reach.
constexpr double kFloatStepsShort = 2.0;
/// The reach of joinsPinchInFace: a pinch the repair leaves is a few of its
/// own steps long (2.4 in the one seen); it is only asked of edges that are
/// refused otherwise.
constexpr double kFloatStepsPinch = 4.0;
double floatShortAt(double extent);

/// Sub-float clusters at a grid vertex: a new vertex of `out` (not a plain
/// marching-tetrahedra vertex, which is the uncut mesh's) whose exact world
/// position lies within kFloatStepsShort float steps (at the grid vertex's
/// largest world coordinate) of the nearest grid vertex G is put at G. A
/// blade plane passing that close to G cuts the edges and faces around it
/// in a cluster of vertices that float cannot tell apart, in every cell
/// around G, and their triangles round to zero area or fold (1 mm head, kerf
/// 0, seed 2044: six vertices within 3e-5 mm of a grid vertex at z = 1045
/// mm, on cube edges and face diagonals that two to four cells share, none
/// of which the float repair may move). At G they are one float point, and
/// the written mesh's snap rounding (fusedMesh: names joined by an edge at
/// one float position are one vertex) joins them and drops the triangles
/// between them. A function of the vertex's name alone (its exact position
/// is), so every cell that has the vertex puts it at G. Returns the
/// vertices moved.
size_t snapToGridVertices(const openvdb::Vec3d& origin, const openvdb::Vec3d& spacing, CutCellGeometry& out);

/// A vertex private to `cell` (inside it, on no cell face: no other cell
/// names it) whose exact position lies inside the cell but whose float world
/// coordinate rounds onto one of the cell's faces is put one float step
/// inside (its index position moved so that it writes there). Rounded into
/// the face, a triangle at it lies in the face, where the cell across has
/// triangles with edges in the face that then run through it (tooth, kerf
/// 0.5, random strokes seed 9127: a vertex 3e-6 mm above the face z = 160
/// mm, a float step there 1.5e-5). Not a tent's apex, a vertex whose
/// neighbours all lie in that face: its triangles lie on a face triangle
/// that both cells of the face flatten alike (repairFloatFolds; 1 mm head,
/// kerf 0.5, seed 9202); nor one a triangle of which would then fold or
/// have no area once written (the centre of a strip of cap thinner than a
/// float step, which the float repair collapses). Run before
/// repairFloatFolds; a function of the cell's geometry alone, so every
/// update and a cut from scratch move the same vertices. Returns the
/// vertices moved.
size_t liftOffCellFaces(const Coord& cell, const openvdb::Vec3d& origin, const openvdb::Vec3d& spacing,
                        CutCellGeometry& out);

/// A vertex inside one of the cell's faces (not the isosurface's own) that
/// lies within kFloatStepsShort float steps of the line of an edge of the
/// face's section (an edge of the cell's triangles in that face, beside it,
/// not beyond its ends) and is written on the line or across it (its float
/// point's side, exactly, differs from its exact side) is written one float
/// step over instead: the first of the eight float neighbours of its point in
/// the face (the face's coordinate kept) that is on the exact side of every
/// such edge; left where none is. Rounded across, the triangles at it and at
/// the edge cross once written (two prisms of a blade pivoting on a corner
/// meet in the face: 2 mm head at -300, kerf 0.5, random strokes seed 9037,
/// a prism's corner line 1.25e-5 mm beside the other's edge at z = 1061 mm,
/// where a float step is 1.2e-4 mm). The face's section is the same in both
/// of its cells (each edge of it has a triangle on either side), and the
/// vertices are taken in name order, so both cells move the same vertices
/// the same way. Run before repairFloatFolds; returns the vertices moved.
size_t keepFaceSidesOnceWritten(const Coord& cell, const openvdb::Vec3d& origin, const openvdb::Vec3d& spacing,
                                CutCellGeometry& out);

/// Float folds (DESIGN invariant 7 once written): a triangle of `out` whose
/// float world position (origin + spacing * index, rounded to float, as
/// CutRemesher::fusedMesh writes it) is degenerate or faces against its exact
/// (double) orientation has folded over; one with an edge shorter than
/// kFloatStepsShort float steps can (its ends round apart across a
/// neighbour, or a vertex just off a cell face rounds onto the face and
/// touches the next cell's triangles), or a face's section doubles back on
/// itself once written. First, in every cell, a shell of the cell's own
/// (every vertex private to it) thinner than a short edge (3 V / A, its
/// inradius when a tetrahedron) goes as a whole: once written it has no
/// inside, and lies on the solid it touches (a tetrahedron 1e-7 mm thick
/// between three slits' sides at kerf 0). Then mended in two steps, all
/// deterministic (a function of `out` and the transform), so incremental,
/// from-scratch and undone geometry stay equal:
/// - a vertex inside one cell face (in a tet face there or on the face's
///   diagonal: held by exactly the two cells of the face, which both have
///   the edge on their boundary) joined by a short edge (short by the
///   face's largest world coordinate, which both cells share) to another
///   vertex of the closed face becomes that one (of two inside the face,
///   the greater name becomes the lesser), pairs taken in name order, in
///   both cells alike; only the link condition is asked, and a common
///   neighbour in the face that fails it keeps the two apart only where
///   both its edges to them are the cell's boundary, as the cell across
///   sees them (a fold or face check might be judged otherwise by the next
///   cell). The rest of the link is the cell's own, which the cell across
///   does not see: common neighbours private to the cell (within
///   kFloatStepsLook float steps) go into the survivor with the pair, so
///   the cell joins the pair where the cell across does (1 mm head, kerf
///   0.5, seed 60027: a vertex 3.3e-4 mm under the face joined to both ends
///   of a pair on the face's diagonal in one cell, collapsed by a round in
///   the other). Where a cell still cannot join (seed 1028 on the 2 mm
///   head, at the sub-micron notch of an unmitred joint, now mitred:
///   makePrismGeom), the seam opens and the local check refuses the
///   update; a triangle it moves into another cell face is listed
///   in out.intoFace (the cell across may make its twin: markCancellingPairs),
///   and it makes no edge along a cube edge, longer than a short edge, from
///   an edge of the face's section (the four cells round the cube edge
///   could each make it, in one of their two faces there);
///   then the two ends of a spike of a face's section (a vertex inside the
///   face joined along it to exactly two vertices inside it, not the
///   isosurface's own, that share no edge and round to one float point) become one, the lesser
///   name, in both cells alike; two triangles that then coincide facing
///   opposite ways go, and the spike's tip with them where it has no other;
/// - then, in rounds, every short edge of the cell, shortest first, and only
///   when none of them can go, a folded triangle's edges (any, shortest
///   first), is collapsed where it can be: a vertex private to the cell
///   (inside it, off its faces, so no other cell names it) moves onto the
///   edge's other end and the two triangles on that edge go, only when that
///   keeps the surface a 2-manifold (the ends share no neighbour but the two apexes, and no
///   triangle comes to lie on another facing the other way: a tetrahedron of the cell's own
///   crushed into two triangles, which the link condition alone allows), folds
///   nothing else over (every remaining triangle at the moved vertex keeps
///   its exact orientation in float) and puts no triangle into a cell face
///   (the next cell may hold the same one), nor an edge it did not have (the cell across
///   may make the same by a collapse of its own: an edge used four times);
///   but where a short edge's
///   collapse would lay every other triangle of the moving end on one of the
///   other end's facing the opposite way (a tetrahedron of the cell's own, a
///   spike of solid thinner than a float step), those pairs go too, and the
///   tetrahedron with them; repeated while it mends.
/// Copies of one point (side or pinch tags differ) are never joined, nor
/// points on opposite sides of one slit; the face rule joins only points of
/// the same tags, a round also points whose tags differ on no slit's side
/// (one on a slit's side, the other off it or on the same side).
/// With `crossings` (a cut with a width: CellKernel runs it on every cell,
/// a second pass after the first without), then also, in rounds, an edge of a triangle that crosses or
/// touches another triangle of the cell once written (as the local check
/// judges it: trianglesCross after snap rounding), shortest first, where a
/// private end can move as above. (It was done only once the local check
/// had failed somewhere, to the cells re-meshed by that update: so a cell
/// mended in a whole cut was left as it was when a step re-meshed it and
/// the check passed, and the live cut of a stroke differed from the cut of
/// the same mask from scratch; 1 mm head, kerf 3, seed 14123.)
/// out.crossFree is set when that pass finds nothing to mend (no crossing,
/// nothing else), and cleared otherwise.
/// With `flattenFoldedTents` (zero kerf, which has no crossings pass), a
/// folded triangle that the rounds leave loses a short edge whose collapse
/// lays a triangle into a cell face, marked in out.intoFace, as the
/// crossings pass does: a tent of three triangles over a triangle of a cell
/// face, its apex inside the cell less than a float step from the face,
/// written into the face with one of its triangles of no area (2 mm head,
/// kerf 0, sawing across the blade, seed 77707: the apex where two slits
/// meet the isosurface, less than a float step from the face z = 1170 mm,
/// on the line of two face vertices 3e-5 mm apart). Every collapse
/// of the apex lays the face triangle under the tent into the face, which
/// the rounds refuse; the face triangle has the tent's rim, edge for edge.
/// Returns the vertices removed.
size_t repairFloatFolds(const Coord& cell, const openvdb::Vec3d& origin, const openvdb::Vec3d& spacing,
                        CutCellGeometry& out, bool crossings = false, bool flattenFoldedTents = false);

/// Snap rounding's second rule (fusedMesh and the local check alike): the
/// edge from a marching-tetrahedra vertex X (`iso`) to another vertex of its
/// grid edge (`other`: on blade planes only, no tag), used twice each way,
/// joins its ends into X when they lie within two float steps (at the grid
/// edge's largest world coordinate) of each other as written (`isoAt`,
/// `otherAt`: float world mm). A blade plane that crosses a grid edge that
/// close to X leaves a sliver of solid round the edge, thinner than float,
/// in every cell round it; the float repair's face rule pinches it in two
/// faces opposite each other across the edge (each face point where the iso
/// line and the blade's line meet goes onto X), and the four cells round the
/// edge each join the plane's vertex to X along the edge (tooth at 400,
/// kerf 0.5, random strokes seed 9076: 6e-6 mm apart at y = 10 mm). Joined,
/// the sliver's four triangles collapse, and the two parts of the solid
/// meet at X alone: a pinch, which fusedMesh splits with kerf > 0. Only an
/// edge the rest of the pipeline refuses (used four times) is asked.
bool joinsAlongGridEdge(const CutVertexId& iso, const CutVertexId& other, const glm::vec3& isoAt, const glm::vec3& otherAt,
                        const openvdb::Vec3d& origin, const openvdb::Vec3d& spacing);

/// Snap rounding's last rule (fusedMesh and the local check alike, after
/// the others, over the names they joined): an edge from a vertex inside a
/// tet face (`other`) to another vertex of the closed face (`keep`: inside
/// it with a lower name, or on one of its edges), both untagged, used twice
/// each way, joins its ends into `keep` (at its position) when they lie
/// within kFloatStepsPinch float steps (at the face's largest world
/// coordinate) of each other as written. Such an edge is a pinch the float
/// repair leaves of a sliver thinner than float:
/// - a prism's corner line (two of its sides' line) meets the isosurface a
///   float step below a cell face, beside where it crosses the face; the
///   notch's four vertices, 3e-4 mm apart, round into the face or collapse
///   (the face rule, repairFloatFolds) in both cells of the face, so each
///   cell's iso and cap triangles meet in the face along the iso line's
///   segment between the two sides, once each way in each cell (1 mm head
///   at 400, kerf 0.5, random strokes seed 9355: 3.4e-4 mm, 2.4 float
///   steps at z = 1209 mm);
/// - an offset plane crosses a tet face inside a cell 8e-6 mm beside the
///   isosurface's vertex on the face's diagonal, and the sliver of solid
///   between them is pinched there from both sides (tooth at 400, kerf 0.5,
///   seed 9273, all four triangles in one cell).
/// Joined, the four triangles on the edge collapse and the two parts of
/// solid meet at one point, a pinch, which fusedMesh splits with kerf > 0
/// (at a marching-tetrahedra vertex, when every cell round its grid edge
/// is cut). Only an edge the rest of the pipeline refuses is asked.
bool joinsPinchInFace(const CutVertexId& keep, const CutVertexId& other, const glm::vec3& keepAt,
                      const glm::vec3& otherAt, const openvdb::Vec3d& origin, const openvdb::Vec3d& spacing);

/// The cheap half of joinsPinchInFace, by name alone.
bool pinchInFaceCandidate(const CutVertexId& keep, const CutVertexId& other);

/// Snap rounding's rules join only the ends of an edge a few float steps
/// long (within kFloatStepsShort or kFloatStepsPinch steps at the largest
/// world coordinate of its grid edge or face, which the cell's bounds; a
/// root a few steps from a name joined into it), so fusedMesh and the local
/// check look only at the edges of a cell's triangles shorter than this:
/// kFloatStepsLook float steps at the cell's largest world coordinate,
/// squared (float world mm).
constexpr double kFloatStepsLook = 16.0;
float snapLookSq(const Coord& cell, const openvdb::Vec3d& origin, const openvdb::Vec3d& spacing);

/// True when a and b lie in two cell faces that meet at a cube edge (their
/// tet faces share its two grid vertices), on the same planes, with the
/// same tags (none, or one side of the same slits): the same curve (e.g.
/// the isosurface's line on a blade plane, a stick between two quads)
/// crossing both faces, which passes that edge closer than the cell it cuts
/// across there is wide. The cheap half of joinsRoundCubeEdge, by name
/// alone.
bool facesMeetAtCubeEdge(const CutVertexId& a, const CutVertexId& b);

/// Snap rounding's rule for such a pair joined by an edge: when both round
/// to within kFloatStepsShort float steps of the cube edge's line (`aAt`,
/// `bAt`: float world mm; the steps at the edge's largest coordinate) and
/// of each other, they are one vertex, the lower name's (1 mm head at 400,
/// kerf 0.5, random strokes seed 9065: the isosurface's line on a kerf
/// plane crosses faces z = 1053 and x = 212 1.6e-5 mm apart beside their
/// edge; rounded onto it, the sliver of isosurface between them lies flat
/// in face z = 1053, and the cap triangle below it, whose edge lies in that
/// face, runs into it; seeds 9103 and 9239: two offset faces' line, one end
/// a float step off the edge; tooth at 400, kerf 0, seed 16215: a stick's
/// two face points on one side of the slit, and the edge's point of the
/// quad, all three on the edge's line once written). Joined, the sliver's
/// triangles collapse.
bool joinsRoundCubeEdge(const CutVertexId& a, const CutVertexId& b, const glm::vec3& aAt, const glm::vec3& bAt,
                        const openvdb::Vec3d& origin, const openvdb::Vec3d& spacing);

} // namespace mtcut::cutter::remesh_detail
