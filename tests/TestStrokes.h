// Blade strokes for tests.
#pragma once

#include "cutter/BladePath.h"

#include <vector>

namespace mtcut::test {

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

} // namespace mtcut::test
