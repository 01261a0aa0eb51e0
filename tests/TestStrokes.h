// Blade strokes for tests.
#pragma once

#include "cutter/BladePath.h"
#include "cutter/CutMask.h"

#include <glm/trigonometric.hpp>

#include <cmath>
#include <vector>

namespace mtcut::test {

/// The path filter as the strokes the tests replay were recorded with:
/// before rule 2c (PathFilterOptions::slideTolerance) held a blade's slides
/// along its own line back, which changes a sliding saw's quads. A replay
/// reproduces a configuration found on those quads (a cell, a quad number).
inline cutter::PathFilterOptions recordedFilter()
{
    cutter::PathFilterOptions o;
    o.slideTolerance = -1.0;
    return o;
}

/// A straight stroke: the base moves from `from` to `to` (world mm) in `steps`
/// poses 1 ms apart, the blade pointing along `dir` with length `len` mm.
inline std::vector<cutter::Pose> straightStroke(glm::dvec3 from, glm::dvec3 to, glm::dvec3 dir, double len, int steps)
{
    std::vector<cutter::Pose> poses;
    for (int i = 0; i <= steps; ++i) {
        cutter::Pose p;
        p.time = 0.001 * i;
        p.base = from + (to - from) * (double(i) / steps);
        p.direction = dir;
        p.length = len;
        poses.push_back(p);
    }
    return poses;
}

/// A saw worked back and forth through the tests' 15 mm balls (centred on
/// the origin, 1 mm voxels), with a hand's tremor: 240 poses, swung 5 mm
/// each way across a 20 mm blade and pushed 0.04 mm deeper a pose
/// (cutter::makeSawingStroke, seed 3). Each pass deepens the cut a little,
/// so the quads it makes depend much on the path filter's retrace tolerance.
inline std::vector<cutter::Pose> sawThroughTheBall()
{
    cutter::SawingOptions o;
    o.poses = 240;
    o.amplitudeMm = 5.0;
    o.feedMm = 0.04;
    o.posesPerCycle = 16.0;
    o.bladeLength = 20.0;
    return cutter::makeSawingStroke(glm::dvec3(0.0, 0.37, 0.0), 3, o);
}

/// A stroke that turns back across its own start, as one new stroke of
/// `mask`: three quads from four vertical sticks round (0.31, 0.27, 0.13)
/// mm, the third crossing the first's base line at (1.31, 0.27, 0.13),
/// inside the third, off its sides (inside the sphere of TestVolumes' and
/// test_render_util's sphereVolume, radius 15 mm round the origin; the
/// point lies in cell (20, 19, 19) there). Zero kerf: that point is in the
/// third quad's slit, a vertex on each side of it.
inline void addRimCrossingStroke(cutter::CutMask& mask)
{
    const glm::dvec3 o(0.31, 0.27, 0.13);
    const glm::dvec3 base[4] = {o, o + glm::dvec3(4, 0, 0), o + glm::dvec3(4, 4, 0), o + glm::dvec3(-2, -4, -5)};
    mask.beginStroke();
    for (uint32_t i = 0; i < 3; ++i) {
        const glm::dvec3 c[4] = {base[i], glm::dvec3(base[i].x, base[i].y, o.z + 10.0),
                                 glm::dvec3(base[i + 1].x, base[i + 1].y, o.z + 10.0), base[i + 1]};
        mask.addQuad(cutter::makeQuad(c, 4, i));
    }
}

/// A stroke that doubles back at an angle, as one new stroke of `mask`: two
/// quads between three vertical sticks 40 mm long through the tests' sphere
/// (radius 15 mm round the origin), the first from x = -4.69 to the stick at
/// (3.31, 0.27) mm, the second from that stick back along a line 20 degrees
/// off the first's (x decreasing), so both quads lie on one side of the
/// stick they share (a zigzag's turn; the stick runs through cells (22, 19,
/// k) there). A quad's normal follows its base's motion (makeQuad), so the
/// second's points the other way from the first's; with `normalsAgree` the
/// second quad's corners are listed from its far stick back and its normal
/// agrees with the first's, as a pivoting blade's can (a base that slides
/// along the blade leaves the orientation to rounding: the tooth at kerf 0,
/// sharp turns, seed 74005, quads 77 and 78 of stroke 2). Zero kerf: the
/// wedge of solid between the two quads and the solid outside them meet
/// along the stick, each with its own copy of it. With `straight` the second
/// quad goes straight on instead (to x = 10.31, in the first one's plane),
/// and `normalsAgree` false makes the two normals exactly opposite (their
/// sum 0).
inline void addFoldedStroke(cutter::CutMask& mask, bool normalsAgree, bool straight = false)
{
    const double a = glm::radians(20.0);
    const glm::dvec3 b(3.31, 0.27, 0.13), up(0, 0, 20);
    const glm::dvec3 base[3] = {b + glm::dvec3(-8, 0, 0), b,
                                straight ? b + glm::dvec3(7, 0, 0) : b + 7.0 * glm::dvec3(-std::cos(a), std::sin(a), 0)};
    mask.beginStroke();
    for (uint32_t i = 0; i < 2; ++i) {
        const glm::dvec3 &p = base[i], &q = base[i + 1];
        const glm::dvec3 c[4] = {p - up, p + up, q + up, q - up};
        const glm::dvec3 r[4] = {q - up, q + up, p + up, p - up};
        mask.addQuad(cutter::makeQuad(i == 1 && normalsAgree ? r : c, 4, i));
    }
}

/// Of the tooth's (at 400) saw swung across its blade, seed 79002 (poses
/// `strokes`, made on its isosurface), stroke 1's quads 20 alone and 26-27
/// as a stroke of their own, added to an empty zero-kerf mask: a reflex cap
/// region of quad 20 in cell (20, 9, 130), tet 0, whose ears on both sides
/// join two rim points (CutPropsDefects.ARimToRimDiagonalOfACapIsSplitOnEachSide).
/// False when the stroke's quads are not the 101 expected.
inline bool addRimDiagonalQuads(cutter::CutMask& mask, const std::vector<std::vector<cutter::Pose>>& strokes)
{
    const std::vector<cutter::Quad> quads = cutter::filterStroke(strokes[1], mask.frame());
    if (quads.size() != 101) return false;
    mask.beginStroke();
    mask.addQuad(quads[20]);
    mask.beginStroke();
    mask.addQuad(quads[26]);
    mask.addQuad(quads[27]);
    return true;
}

} // namespace mtcut::test
