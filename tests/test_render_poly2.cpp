// The GPU cut pass's 2-D polygon helpers (shaders/poly2.glsl) decide exactly
// as the CPU's (cutter/Polygon2.h): seeded random polygons - convex and not,
// straight corners, slivers 1e-12 off a line, repeated points, tiny features
// at coordinates of 1e3, holes touching the outer loop or bridged over tied
// candidates, more corners than the shader holds - run through both, and the
// shader's answers (bools, triangle and loop index lists, the doubles'
// bits) equal the C++'s, or, where the C++ result would not fit the
// shader's capacities, the shader says it overflowed.
#include "cutter/Polygon2.h"
#include "render/CutKernelGpu.h"
#include "render/GlObjects.h"
#include "render/Shaders.h"
#include "tests/test_render_util.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <limits>
#include <random>
#include <sstream>
#include <string>
#include <vector>

using namespace mtcut;
using namespace mtcut::cutter::poly2;
using namespace mtcut::render;

namespace {

// The shader's capacities, set through its defines.
constexpr int kMax = 64, kMaxPoints = 64, kMaxHoles = 8, kMaxTris = 64;
constexpr size_t kRecord = 16 + 3 * kMaxTris + kMax; // POLY2_RECORD of poly2_test.comp

enum Func : int { kSegments, kTriangle, kArea, kBest, kEarClip, kBridge, kFuncCount };
const char* const kFuncNames[kFuncCount] = {"segmentsIntersect", "minSine/cross2/length2/same2", "signedArea",
                                            "bestTriangulation", "earClip", "bridgeHoles + earClip"};

struct Input
{
    Func func;
    int repeat = 1;
    std::vector<Vec2> pts;
    std::vector<int> poly;
    std::vector<std::vector<int>> holes;
    std::string kind;
};

/// What a case answers: the fields of poly2_test.comp's record.
struct Answer
{
    bool r0 = false, r1 = false, overflow = false;
    std::vector<int> tris, poly;
    uint64_t bits[4] = {0, 0, 0, 0};
};

uint64_t bitsOf(double d)
{
    uint64_t u;
    std::memcpy(&u, &d, sizeof u);
    return u;
}

double doubleOf(uint64_t u)
{
    double d;
    std::memcpy(&d, &u, sizeof d);
    return d;
}

/// Does the input itself exceed the shader's capacities?
bool inputTooBig(const Input& in)
{
    size_t holeCorners = 0;
    for (const auto& h : in.holes) holeCorners += h.size();
    return in.pts.size() > size_t(kMaxPoints) || in.poly.size() > size_t(kMax) || in.holes.size() > size_t(kMaxHoles) ||
           holeCorners > size_t(kMax);
}

/// The C++ answer.
Answer cpuAnswer(const Input& in)
{
    Answer a;
    const std::vector<Vec2>& p = in.pts;
    a.poly = in.poly;
    switch (in.func) {
    case kSegments:
        a.r0 = segmentsIntersect(p[0], p[1], p[2], p[3]);
        // Its four orientations too, in the shader's order: a wrong answer
        // then shows which product the GPU rounded differently.
        a.bits[0] = bitsOf(cross2(p[2], p[3], p[0]));
        a.bits[1] = bitsOf(cross2(p[2], p[3], p[1]));
        a.bits[2] = bitsOf(cross2(p[0], p[1], p[2]));
        a.bits[3] = bitsOf(cross2(p[0], p[1], p[3]));
        break;
    case kTriangle:
        a.bits[0] = bitsOf(minSine(p[0], p[1], p[2]));
        a.bits[1] = bitsOf(cross2(p[0], p[1], p[2]));
        a.bits[2] = bitsOf(length2(p[1].x - p[0].x, p[1].y - p[0].y));
        a.r0 = same2(p[0], p[1]);
        break;
    case kArea: a.bits[0] = bitsOf(signedArea(in.poly, p)); break;
    case kBest:
    case kEarClip:
        for (int k = 0; k < in.repeat; ++k) {
            a.r0 = in.func == kBest ? bestTriangulation(in.poly, p, a.tris) : earClip(in.poly, p, a.tris);
            if (!a.r0) break;
        }
        break;
    case kBridge:
        a.r0 = bridgeHoles(a.poly, in.holes, p);
        if (a.r0) a.r1 = earClip(a.poly, p, a.tris);
        break;
    default: break;
    }
    // Whatever the shader cannot hold it must refuse: the polygon only grows
    // and triangles are only appended, so it overflows exactly when the C++
    // ends up with more than it holds.
    a.overflow = inputTooBig(in) || a.tris.size() > size_t(3 * kMaxTris) || a.poly.size() > size_t(kMax);
    return a;
}

Answer gpuAnswer(const uint32_t* rec)
{
    Answer a;
    a.r0 = rec[0] != 0;
    a.r1 = rec[1] != 0;
    a.overflow = rec[2] != 0;
    const uint32_t triCount = std::min<uint32_t>(rec[3], 3 * kMaxTris), polyCount = std::min<uint32_t>(rec[4], kMax);
    for (uint32_t k = 0; k < triCount; ++k) a.tris.push_back(int(rec[16 + k]));
    for (uint32_t k = 0; k < polyCount; ++k) a.poly.push_back(int(rec[16 + 3 * kMaxTris + k]));
    for (int k = 0; k < 4; ++k) a.bits[k] = uint64_t(rec[8 + 2 * k]) | uint64_t(rec[9 + 2 * k]) << 32;
    return a;
}

std::string listText(const std::vector<int>& v)
{
    std::ostringstream s;
    for (size_t i = 0; i < v.size(); ++i) s << (i ? " " : "") << v[i];
    return s.str();
}

/// Empty when the answers agree, else what differs.
/// Both zero, of either sign. No caller reads the sign of a zero these
/// functions return (an orientation of 0 is collinear whatever its sign;
/// angleLess, which read one through atan2's order, no longer does), and
/// NVIDIA's 580 driver gives -0 for +0 in some orientations (124 of the
/// 4,000 segment cases on an H200): counted, not a difference.
bool sameZero(uint64_t a, uint64_t b) { return doubleOf(a) == 0.0 && doubleOf(b) == 0.0; }

std::string difference(const Answer& cpu, const Answer& gpu)
{
    std::ostringstream s;
    if (cpu.overflow != gpu.overflow) s << " overflow cpu " << cpu.overflow << " gpu " << gpu.overflow << ";";
    if (cpu.overflow) {
        if (gpu.r0 || gpu.r1) s << " overflowed but returned true;";
        return s.str();
    }
    if (cpu.r0 != gpu.r0) s << " result cpu " << cpu.r0 << " gpu " << gpu.r0 << ";";
    if (cpu.r1 != gpu.r1) s << " second result cpu " << cpu.r1 << " gpu " << gpu.r1 << ";";
    if (cpu.tris != gpu.tris) s << " tris cpu [" << listText(cpu.tris) << "] gpu [" << listText(gpu.tris) << "];";
    if (cpu.poly != gpu.poly) s << " polygon cpu [" << listText(cpu.poly) << "] gpu [" << listText(gpu.poly) << "];";
    for (int k = 0; k < 4; ++k)
        if (cpu.bits[k] != gpu.bits[k] && !sameZero(cpu.bits[k], gpu.bits[k])) {
            char t[128];
            std::snprintf(t, sizeof t, " double %d cpu %.17g (%016llx) gpu %.17g (%016llx);", k, doubleOf(cpu.bits[k]),
                          (unsigned long long)cpu.bits[k], doubleOf(gpu.bits[k]), (unsigned long long)gpu.bits[k]);
            s << t;
        }
    return s.str();
}

std::string inputText(const Input& in)
{
    std::ostringstream s;
    s.precision(17);
    s << kFuncNames[in.func] << " (" << in.kind << ", repeat " << in.repeat << ") pts";
    for (const Vec2& p : in.pts) s << " (" << p.x << ", " << p.y << ")";
    s << " poly [" << listText(in.poly) << "]";
    for (const auto& h : in.holes) s << " hole [" << listText(h) << "]";
    return s.str();
}

/// Runs every case through poly2_test.comp; one record of kRecord uints each.
std::vector<uint32_t> runShader(const std::vector<Input>& inputs, double& compileMs, double& runMs)
{
    struct Case
    {
        int32_t func, repeat, pointStart, pointCount, polyStart, polyCount, holeStart, holeCount;
    };
    static_assert(sizeof(Case) == 32 && sizeof(Vec2) == 16, "std430 layouts of poly2_test.comp");
    std::vector<Case> cases;
    std::vector<Vec2> points;
    std::vector<int32_t> indices;
    for (const Input& in : inputs) {
        Case c{in.func, in.repeat, int32_t(points.size()), int32_t(in.pts.size()), int32_t(indices.size()),
               int32_t(in.poly.size()), 0, int32_t(in.holes.size())};
        points.insert(points.end(), in.pts.begin(), in.pts.end());
        indices.insert(indices.end(), in.poly.begin(), in.poly.end());
        c.holeStart = int32_t(indices.size());
        for (const auto& h : in.holes) indices.push_back(int32_t(h.size()));
        for (const auto& h : in.holes) indices.insert(indices.end(), h.begin(), h.end());
        cases.push_back(c);
    }
    indices.push_back(0); // never empty
    const auto t0 = std::chrono::steady_clock::now();
    const std::string defines = "#define POLY2_MAX " + std::to_string(kMax) + "\n#define POLY2_MAX_POINTS " +
                                std::to_string(kMaxPoints) + "\n#define POLY2_MAX_HOLES " + std::to_string(kMaxHoles) +
                                "\n#define POLY2_MAX_TRIS " + std::to_string(kMaxTris) + "\n" +
                                render::poly2Library();
    const Program program = buildProgram({"poly2_test.comp"}, defines);
    const auto t1 = std::chrono::steady_clock::now();
    const Buffer caseBuf(cases.size() * sizeof(Case), cases.data());
    const Buffer pointBuf(points.size() * sizeof(Vec2), points.data());
    const Buffer indexBuf(indices.size() * sizeof(int32_t), indices.data());
    const Buffer resultBuf(cases.size() * kRecord * sizeof(uint32_t), nullptr, GL_MAP_READ_BIT);
    program.use();
    glProgramUniform1ui(program.id(), program.uniform("uCount"), GLuint(cases.size()));
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 0, caseBuf.id());
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 1, pointBuf.id());
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 2, indexBuf.id());
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 3, resultBuf.id());
    glDispatchCompute(GLuint((cases.size() + 15) / 16), 1, 1);
    glMemoryBarrier(GL_BUFFER_UPDATE_BARRIER_BIT);
    std::vector<uint32_t> result(cases.size() * kRecord);
    glGetNamedBufferSubData(resultBuf.id(), 0, GLsizeiptr(result.size() * sizeof(uint32_t)), result.data());
    glUseProgram(0);
    checkGlError("poly2_test.comp");
    const auto t2 = std::chrono::steady_clock::now();
    compileMs = std::chrono::duration<double, std::milli>(t1 - t0).count();
    runMs = std::chrono::duration<double, std::milli>(t2 - t1).count();
    return result;
}

// ---- Polygons. Shapes are made about the origin at unit size, CCW, then
// placed: rotated, scaled and moved (to 1e3 with features of 1e-6, as the
// kernel's planes at z = 1100 see them).

class Gen
{
public:
    explicit Gen(uint64_t seed) : mRng(seed) {}

    double uniform(double a, double b) { return std::uniform_real_distribution<double>(a, b)(mRng); }
    int integer(int a, int b) { return std::uniform_int_distribution<int>(a, b)(mRng); }
    bool chance(double p) { return uniform(0.0, 1.0) < p; }

    /// n corners at sorted random angles, radius in [rMin, 1]: convex when rMin = 1.
    std::vector<Vec2> star(int n, double rMin)
    {
        std::vector<double> ang(size_t(n), 0.0);
        for (double& a : ang) a = uniform(0.0, 2.0 * M_PI);
        std::sort(ang.begin(), ang.end());
        std::vector<Vec2> out;
        for (double a : ang) {
            const double r = rMin >= 1.0 ? 1.0 : uniform(rMin, 1.0);
            out.push_back({r * std::cos(a), r * std::sin(a)});
        }
        return out;
    }

    /// The star snapped to a grid of g steps per unit: exact ties of scores
    /// and distances, straight corners, repeated points.
    std::vector<Vec2> gridStar(int n, double rMin, int g)
    {
        std::vector<Vec2> out = star(n, rMin);
        for (Vec2& p : out) p = {std::round(p.x * g) / g, std::round(p.y * g) / g};
        return out;
    }

    /// An axis-aligned w x h box of integer corners with every lattice point
    /// of its sides as a corner (straight corners everywhere), from (-w/2, -h/2).
    static std::vector<Vec2> latticeBox(int w, int h)
    {
        std::vector<Vec2> out;
        const double x0 = -0.5 * w, y0 = -0.5 * h;
        for (int i = 0; i < w; ++i) out.push_back({x0 + i, y0});
        for (int j = 0; j < h; ++j) out.push_back({x0 + w, y0 + j});
        for (int i = w; i > 0; --i) out.push_back({x0 + i, y0 + h});
        for (int j = h; j > 0; --j) out.push_back({x0, y0 + j});
        return out;
    }

    /// An integer L, U or T of n-ish corners: non-convex, straight corners, ties.
    std::vector<Vec2> rectilinear()
    {
        switch (integer(0, 2)) {
        case 0: return {{0, 0}, {2, 0}, {2, 1}, {1, 1}, {1, 2}, {0, 2}};
        case 1: return {{0, 0}, {3, 0}, {3, 2}, {2, 2}, {2, 1}, {1, 1}, {1, 2}, {0, 2}};
        default: return {{1, 0}, {2, 0}, {2, 2}, {3, 2}, {3, 3}, {0, 3}, {0, 2}, {1, 2}};
        }
    }

    /// Points along a line, `eps` off it on both sides (some exactly on it):
    /// a polygon that is all sliver.
    std::vector<Vec2> sliver(int n, double eps)
    {
        std::vector<Vec2> out;
        const int lower = std::max(2, n / 2);
        for (int i = 0; i < lower; ++i) out.push_back({double(i) / (lower - 1), i == 0 || i == lower - 1 ? 0.0 : -eps});
        for (int i = n - lower; i > 0; --i) out.push_back({double(i) / (n - lower + 1), eps * (i % 3)});
        return out;
    }

    /// Puts extra corners on some sides: exactly on them (straight corners,
    /// up to rounding) or `off` away from them, inwards or outwards.
    void addStraight(std::vector<Vec2>& p, int count, double off)
    {
        for (int c = 0; c < count && p.size() < 200; ++c) {
            const size_t i = size_t(integer(0, int(p.size()) - 1));
            const Vec2 a = p[i], b = p[(i + 1) % p.size()];
            const double t = std::vector<double>{0.5, 0.25, 1.0 / 3.0, 0.75}[size_t(integer(0, 3))];
            const double dx = b.x - a.x, dy = b.y - a.y, l = std::sqrt(dx * dx + dy * dy);
            const double o = off == 0.0 || l == 0.0 ? 0.0 : (chance(0.5) ? off : -off) / l;
            p.insert(p.begin() + long(i) + 1, Vec2{a.x + t * dx - o * dy, a.y + t * dy + o * dx});
        }
    }

    /// A spike into the polygon and back to a copy of its corner (a slit).
    void addSlit(std::vector<Vec2>& p)
    {
        const size_t i = size_t(integer(0, int(p.size()) - 1));
        const Vec2 a = p[i], c{0.5 * p[i].x, 0.5 * p[i].y};
        p.insert(p.begin() + long(i) + 1, {c, a});
    }

    /// Rotates, scales and moves the points.
    void place(std::vector<Vec2>& p, int how)
    {
        double scale = 1.0, ox = 0.0, oy = 0.0, rot = 0.0;
        switch (how) {
        case 0: break;                                                       // as made
        case 1: rot = uniform(0.0, 2.0 * M_PI); scale = uniform(0.1, 10.0); break;
        case 2: rot = uniform(0.0, 2.0 * M_PI); scale = 1e-3; ox = 1100.0; oy = -731.25; break;
        case 3: scale = 1e-6; ox = 1000.0; oy = 1100.0; rot = uniform(0.0, 2.0 * M_PI); break;
        case 4: scale = 1e-9; ox = -1100.0; oy = 512.0; break;              // a few thousand ulps
        default: scale = 37.5; ox = 3.0; oy = -2.0; rot = 0.5 * M_PI; break; // a quarter turn, rounded
        }
        const double c = std::cos(rot), s = std::sin(rot);
        for (Vec2& q : p) q = {ox + scale * (c * q.x - s * q.y), oy + scale * (s * q.x + c * q.y)};
    }

    int placement() { return chance(0.3) ? 0 : integer(1, 5); }

    /// A polygon of about n corners of one of the kinds, placed.
    std::vector<Vec2> polygon(int n, std::string& kind)
    {
        std::vector<Vec2> p;
        const int k = integer(0, 10);
        const int side = std::max(1, n / 4);
        const double offs[4] = {1e-12, 1e-9, 1.5e-9, 1e-6}, slivers[4] = {1e-12, 1e-9, 1e-15, 0.0};
        switch (k) {
        case 0: p = star(n, 1.0); kind = "convex"; break;
        case 1: p = star(n, 0.2); kind = "star"; break;
        case 2: p = gridStar(n, 0.3, integer(2, 6)); kind = "grid star"; break;
        case 3: p = latticeBox(integer(1, side), integer(1, side)); kind = "lattice box"; break;
        case 4: p = rectilinear(); kind = "rectilinear"; break;
        case 5: p = sliver(std::max(3, n), slivers[integer(0, 3)]); kind = "sliver"; break;
        case 6: p = star(std::max(3, n - 2), 0.5); addStraight(p, 2, 0.0); kind = "straight corners"; break;
        case 7:
            p = star(std::max(3, n - 2), 0.5);
            addStraight(p, 2, offs[integer(0, 3)]);
            kind = "near straight";
            break;
        case 8: p = star(std::max(3, n - 2), 0.4); addSlit(p); kind = "slit"; break;
        case 9: {
            // A corner right at the tolerance outside the chord of its
            // neighbours: cross2 against the chord (0,0)-(1,0) is y exactly,
            // the bound -1e-9 * 1 * 1; a few ulps either way.
            double y = -1e-9;
            const int ulps = integer(-4, 4);
            for (int u = 0; u < std::abs(ulps); ++u) y = std::nextafter(y, ulps > 0 ? 1.0 : -1.0);
            p = {{0, 0}, {0.5, y}, {1, 0}, {1, 1}};
            const int top = integer(0, std::max(0, n - 5));
            for (int i = 0; i < top; ++i) p.push_back({1.0 - (i + 1.0) / (top + 1.0), 1.0 + uniform(0.0, 0.2)});
            p.push_back({0, 1});
            kind = "a corner 1e-9 off its chord, " + std::to_string(ulps) + " ulps";
            return p; // placed as made: moving it would round the boundary away
        }
        default:
            for (int i = 0; i < n; ++i) p.push_back({uniform(-1.0, 1.0), uniform(-1.0, 1.0)});
            kind = "random (self-crossing)";
            break;
        }
        const int how = placement();
        place(p, how);
        kind += " at " + std::to_string(how);
        return p;
    }

private:
    std::mt19937_64 mRng;
};

/// The polygon's indices: in order, sometimes with a repeated corner (the
/// same index twice, or a copy of its point).
std::vector<int> indexPolygon(Gen& g, std::vector<Vec2>& pts, size_t n, std::string& kind)
{
    std::vector<int> poly(n);
    for (size_t i = 0; i < n; ++i) poly[i] = int(i);
    if (n >= 3 && g.chance(0.08)) {
        const size_t i = size_t(g.integer(0, int(n) - 1));
        if (g.chance(0.5)) {
            poly.insert(poly.begin() + long(i), poly[i]);
            kind += ", an index twice";
        } else {
            pts.push_back(pts[i]);
            poly.insert(poly.begin() + long(i), int(pts.size() - 1));
            kind += ", a point twice";
        }
    }
    return poly;
}

Input polygonCase(Gen& g, Func f, int nMin, int nMax)
{
    Input in;
    in.func = f;
    in.pts = g.polygon(g.integer(nMin, nMax), in.kind);
    in.poly = indexPolygon(g, in.pts, in.pts.size(), in.kind);
    if (g.chance(0.05)) { // the same polygon, its points listed in another order
        std::vector<int> perm(in.pts.size());
        for (size_t i = 0; i < perm.size(); ++i) perm[i] = int(i);
        std::shuffle(perm.begin(), perm.end(), std::mt19937(uint32_t(g.integer(0, 1 << 30))));
        std::vector<Vec2> shuffled(in.pts.size());
        for (size_t i = 0; i < perm.size(); ++i) shuffled[size_t(perm[i])] = in.pts[i];
        in.pts = shuffled;
        for (int& i : in.poly) i = perm[size_t(i)];
        in.kind += ", shuffled points";
    }
    return in;
}

/// A CCW outer loop with 1-3 CW holes: apart, touching the outer loop (a
/// copy of one of its corners), or placed so that bridge candidates tie.
Input bridgeCase(Gen& g)
{
    Input in;
    in.func = kBridge;
    const int holes = g.integer(1, 3);
    const int style = g.integer(0, 6);
    auto addLoop = [&](std::vector<Vec2> loop, bool cw) {
        double a = 0.0;
        for (size_t i = 0; i < loop.size(); ++i)
            a += loop[i].x * loop[(i + 1) % loop.size()].y - loop[i].y * loop[(i + 1) % loop.size()].x;
        if ((a > 0) == cw) std::reverse(loop.begin(), loop.end());
        std::vector<int> idx;
        for (const Vec2& p : loop) {
            in.pts.push_back(p);
            idx.push_back(int(in.pts.size() - 1));
        }
        return idx;
    };
    if (style == 0 || style == 1) {
        // Ties: a lattice square with corners every 5 (or 10), holes as small
        // lattice squares symmetric about the axes.
        const int step = style == 0 ? 5 : 10;
        std::vector<Vec2> outer;
        for (int i = -10; i < 10; i += step) outer.push_back({double(i), -10});
        for (int j = -10; j < 10; j += step) outer.push_back({10, double(j)});
        for (int i = 10; i > -10; i -= step) outer.push_back({double(i), 10});
        for (int j = 10; j > -10; j -= step) outer.push_back({-10, double(j)});
        in.poly = addLoop(outer, false);
        const Vec2 centres[3] = {{0, 0}, {-5, 5}, {5, -5}};
        for (int h = 0; h < holes; ++h) {
            const double r = g.integer(1, 2);
            std::vector<Vec2> sq = {{centres[h].x - r, centres[h].y - r}, {centres[h].x + r, centres[h].y - r},
                                    {centres[h].x + r, centres[h].y + r}, {centres[h].x - r, centres[h].y + r}};
            if (g.chance(0.3)) sq = {{centres[h].x, centres[h].y - r}, {centres[h].x + r, centres[h].y},
                                     {centres[h].x, centres[h].y + r}, {centres[h].x - r, centres[h].y}}; // a diamond
            in.holes.push_back(addLoop(sq, true));
        }
        in.kind = style == 0 ? "lattice, ties" : "lattice square, ties";
    } else if (style >= 5) {
        // Cracks: zero-width slits with a point midway held twice, once per
        // side (the kernel's blade stopping inside a region), as holes
        // M+ -> B -> M- -> A; with style 6 the first one runs from a copy of
        // an outer corner (a slit from the boundary).
        std::vector<Vec2> outer = g.star(g.integer(3, 12), style == 5 ? 1.0 : 0.9);
        for (Vec2& p : outer) p = {8.0 * p.x, 8.0 * p.y};
        in.poly = addLoop(outer, false);
        for (int h = 0; h < holes; ++h) {
            const double a = 2.0 * M_PI * h / 3.0 + g.uniform(0.0, 0.5), t = g.uniform(0.0, M_PI);
            const Vec2 c{3.5 * std::cos(a), 3.5 * std::sin(a)}, d{1.5 * std::cos(t), 1.5 * std::sin(t)};
            Vec2 from{c.x - d.x, c.y - d.y}, to{c.x + d.x, c.y + d.y};
            int fromIndex = -1;
            if (style == 6 && h == 0) {
                fromIndex = in.poly[size_t(g.integer(0, int(in.poly.size()) - 1))];
                from = in.pts[size_t(fromIndex)];
                to = {0.5 * (from.x + c.x), 0.5 * (from.y + c.y)};
            }
            const Vec2 m{0.5 * (from.x + to.x), 0.5 * (from.y + to.y)};
            const int s0 = int(in.pts.size());
            in.pts.insert(in.pts.end(), {m, to, m, from});
            std::vector<int> crack = {s0, s0 + 1, s0 + 2, s0 + 3};
            if (fromIndex >= 0 && g.chance(0.5)) crack[3] = fromIndex; // the very same index
            std::rotate(crack.begin(), crack.begin() + g.integer(0, 3), crack.end());
            in.holes.push_back(crack);
        }
        in.kind = style == 5 ? "cracks" : "cracks, one from the boundary";
    } else {
        std::vector<Vec2> outer = style == 2 ? g.star(g.integer(3, 24), 1.0) : g.star(g.integer(5, 24), 0.85);
        for (Vec2& p : outer) p = {8.0 * p.x, 8.0 * p.y};
        if (g.chance(0.3)) g.addStraight(outer, 2, 0.0);
        in.poly = addLoop(outer, false);
        for (int h = 0; h < holes; ++h) {
            // Slots 120 degrees apart at radius 3.5: holes of radius <= 1.5 never meet.
            const double a = 2.0 * M_PI * h / 3.0 + 0.3;
            const Vec2 c{3.5 * std::cos(a), 3.5 * std::sin(a)};
            std::vector<Vec2> hole;
            const int kind2 = g.integer(0, 3);
            if (kind2 == 0) hole = g.star(g.integer(3, 8), 1.0);
            else if (kind2 == 1) hole = g.star(g.integer(3, 8), 0.3);
            else if (kind2 == 2) hole = g.gridStar(g.integer(3, 8), 0.5, 2);
            else hole = {{-1, 0}, {1, 0}, {0, 0}}; // zero area: a slit of a hole
            for (Vec2& p : hole) p = {c.x + 1.5 * p.x, c.y + 1.5 * p.y};
            in.holes.push_back(addLoop(hole, true));
        }
        in.kind = style == 2 ? "convex outer" : "star outer";
        if (style == 4) {
            // The first hole touches the outer loop: one of its corners is a
            // copy of an outer corner, the rest pulled in towards the centre.
            const size_t o = size_t(g.integer(0, int(in.poly.size()) - 1));
            const Vec2 at = in.pts[size_t(in.poly[o])];
            std::vector<Vec2> hole = {at, {0.7 * at.x + 0.3, 0.7 * at.y - 0.2}, {0.7 * at.x - 0.3, 0.7 * at.y + 0.2}};
            in.holes[0] = addLoop(hole, true);
            if (g.chance(0.5)) { // the very same index
                for (int& i : in.holes[0])
                    if (same2(in.pts[size_t(i)], at)) i = in.poly[o];
            }
            in.kind += ", a hole touching";
        }
    }
    const int how = g.placement();
    g.place(in.pts, how);
    in.kind += " at " + std::to_string(how);
    return in;
}

Input segmentCase(Gen& g)
{
    Input in;
    in.func = kSegments;
    const int k = g.integer(0, 4);
    if (k == 0) { // a small lattice: collinear, touching, shared ends
        for (int i = 0; i < 4; ++i) in.pts.push_back({double(g.integer(0, 3)), double(g.integer(0, 3))});
        in.kind = "lattice";
    } else if (k == 1) {
        for (int i = 0; i < 4; ++i) in.pts.push_back({g.uniform(-1, 1), g.uniform(-1, 1)});
        in.kind = "random";
    } else if (k == 2) { // points on one line, up to rounding
        const Vec2 a{g.uniform(-1, 1), g.uniform(-1, 1)}, b{g.uniform(-1, 1), g.uniform(-1, 1)};
        for (int i = 0; i < 4; ++i) {
            const double t = 0.25 * g.integer(-2, 6);
            in.pts.push_back({a.x + t * (b.x - a.x), a.y + t * (b.y - a.y)});
        }
        in.kind = "collinear";
    } else if (k == 3) { // a shared end, or an end on the other's inside
        for (int i = 0; i < 3; ++i) in.pts.push_back({g.uniform(-1, 1), g.uniform(-1, 1)});
        const Vec2 a = in.pts[0], b = in.pts[1];
        in.pts.push_back(g.chance(0.5) ? in.pts[size_t(g.integer(0, 1))] : Vec2{0.5 * (a.x + b.x), 0.5 * (a.y + b.y)});
        if (g.chance(0.5)) std::swap(in.pts[2], in.pts[3]);
        in.kind = "touching";
    } else { // 1e-12 off: near-touching
        for (int i = 0; i < 3; ++i) in.pts.push_back({g.uniform(-1, 1), g.uniform(-1, 1)});
        const Vec2 a = in.pts[0], b = in.pts[1];
        in.pts.push_back({0.5 * (a.x + b.x) + g.uniform(-1e-12, 1e-12), 0.5 * (a.y + b.y) + g.uniform(-1e-12, 1e-12)});
        in.kind = "near touching";
    }
    const int how = g.placement();
    g.place(in.pts, how);
    in.kind += " at " + std::to_string(how);
    return in;
}

Input triangleCase(Gen& g)
{
    Input in;
    in.func = kTriangle;
    const int k = g.integer(0, 3);
    if (k == 0) {
        for (int i = 0; i < 3; ++i) in.pts.push_back({double(g.integer(0, 2)), double(g.integer(0, 2))});
        in.kind = "lattice";
    } else if (k == 1) {
        for (int i = 0; i < 3; ++i) in.pts.push_back({g.uniform(-1, 1), g.uniform(-1, 1)});
        in.kind = "random";
    } else if (k == 2) {
        const Vec2 a{g.uniform(-1, 1), g.uniform(-1, 1)}, b{g.uniform(-1, 1), g.uniform(-1, 1)};
        const double off = std::vector<double>{0.0, 1e-12, -1e-12, 1e-15}[size_t(g.integer(0, 3))];
        in.pts = {a, b, {0.5 * (a.x + b.x) + off, 0.5 * (a.y + b.y) - off}};
        in.kind = "sliver";
    } else {
        const Vec2 a{g.uniform(-1, 1), g.uniform(-1, 1)};
        in.pts = {a, a, {g.uniform(-1, 1), g.uniform(-1, 1)}};
        std::rotate(in.pts.begin(), in.pts.begin() + g.integer(0, 2), in.pts.end());
        in.kind = "repeated point";
    }
    const int how = g.placement();
    g.place(in.pts, how);
    in.kind += " at " + std::to_string(how);
    return in;
}

/// Polygons larger than the shader holds, or whose results are.
std::vector<Input> overflowCases()
{
    std::vector<Input> out;
    Gen g(99);
    Input big;
    big.func = kEarClip;
    big.pts = g.star(kMax + 6, 1.0);
    for (size_t i = 0; i < big.pts.size(); ++i) big.poly.push_back(int(i));
    big.kind = "more corners than POLY2_MAX";
    out.push_back(big);

    Input twice; // 2 x 38 triangles into one list of 64
    twice.func = kEarClip;
    twice.repeat = 2;
    twice.pts = g.star(40, 0.5);
    for (size_t i = 0; i < twice.pts.size(); ++i) twice.poly.push_back(int(i));
    twice.kind = "more triangles than POLY2_MAX_TRIS";
    out.push_back(twice);

    Input bestTwice; // 9 x 7 triangles fit, 10 x 7 do not
    bestTwice.func = kBest;
    bestTwice.repeat = 10;
    bestTwice.pts = g.star(9, 1.0);
    for (size_t i = 0; i < bestTwice.pts.size(); ++i) bestTwice.poly.push_back(int(i));
    bestTwice.kind = "bestTriangulation into a full list";
    out.push_back(bestTwice);

    Input bridged; // 40 + 3 x 8 points fit; bridged, 40 + 3 x (8 + 2) corners do not
    bridged.func = kBridge;
    bridged.pts = g.star(40, 1.0);
    for (Vec2& p : bridged.pts) p = {8.0 * p.x, 8.0 * p.y};
    for (size_t i = 0; i < bridged.pts.size(); ++i) bridged.poly.push_back(int(i));
    for (int h = 0; h < 3; ++h) {
        std::vector<Vec2> hole = g.star(8, 1.0);
        std::reverse(hole.begin(), hole.end());
        std::vector<int> idx;
        for (const Vec2& p : hole) {
            const double a = 2.0 * M_PI * h / 3.0;
            bridged.pts.push_back({3.5 * std::cos(a) + p.x, 3.5 * std::sin(a) + p.y});
            idx.push_back(int(bridged.pts.size() - 1));
        }
        bridged.holes.push_back(idx);
    }
    bridged.kind = "bridged polygon over POLY2_MAX";
    out.push_back(bridged);

    Input manyHoles; // more holes than POLY2_MAX_HOLES
    manyHoles.func = kBridge;
    manyHoles.pts = {{-20, -20}, {20, -20}, {20, 20}, {-20, 20}};
    manyHoles.poly = {0, 1, 2, 3};
    for (int h = 0; h < kMaxHoles + 1; ++h) {
        const double x = -16.0 + 4.0 * h;
        const size_t s = manyHoles.pts.size();
        manyHoles.pts.insert(manyHoles.pts.end(), {{x, 0}, {x, 1}, {x + 1, 1}});
        manyHoles.holes.push_back({int(s), int(s + 1), int(s + 2)});
    }
    manyHoles.kind = "more holes than POLY2_MAX_HOLES";
    out.push_back(manyHoles);
    return out;
}

} // namespace

// Each path by which a shader can take a double (a buffer, a function, a
// parameter) and each kind of storage it can keep one in, with the plain
// operations on it: those the cut pass's shaders use must keep every bit.
// Written after poly2_test.comp's answers on an NVIDIA H100 (driver
// 580.159.04) came out as double arithmetic on float-rounded points; this
// test found the cause there: a dvec2 kept in a private array indexed at run
// time comes back rounded to float. The storage the shaders avoid is only
// reported (it describes the driver, not our code); a failure names the path.
// Also division and square root (GLSL asks no correct rounding of them):
// the driver's division, which the shaders use, must be exact; its square
// root is only reported (an ulp off for a quarter of the inputs on that
// H100); the shaders take roots through doubles.glsl's dSqrt, asserted here,
// as are its corrections of a quotient and a root an ulp off.
TEST(RenderPoly2, DoublesReachTheShaderUnrounded)
{
    MTCUT_REQUIRE_GL();
    struct Path
    {
        const char* name;
        bool must; // used by the cut pass's shaders (poly2.glsl, cut_*.glsl), or meant to be: asserted
                   // (they keep no double in a private array: cut_kernel.glsl's D3GET and kin)
    };
    constexpr int kPaths = 29, kPlainCross = 10; // the one path compared loosely
    const Path paths[kPaths] = {{"dvec2 buffer .x", true},
                                {"dvec2 buffer .y", true},
                                {"double buffer", true},
                                {"global dvec2 array (run-time index)", false},
                                {"function", true},
                                {"global dvec2 array via function", false},
                                {"x - y", true},
                                {"x * y", true},
                                {"cross product", true},
                                {"precise cross in a function, of a point kept as bits", true},
                                {"the same without precise (within 4 ulp: it may fuse)", true},
                                {"dvec2 buffer at an index from another buffer", true},
                                {"global double array", false},
                                {"global dvec3 array", false},
                                {"global dvec4 array", false},
                                {"a function's dvec2 array", false},
                                {"a function's double array", false},
                                {"dvec3 array in a global struct", false},
                                {"dvec3 component read at a run-time index", true},
                                {"dvec2 as bits (uvec4 array)", true},
                                {"double as bits (uvec2 array)", true},
                                {"double as uint64_t bits", false},
                                {"out dvec3[4] parameter", false},
                                {"x / y", true},
                                {"sqrt(|x|), the driver's", false}, // an ulp off on NVIDIA: the shaders use dSqrt
                                {"x / y corrected from the driver's (or an ulp off)", true},
                                {"sqrt(|x|) corrected likewise", true},
                                {"a cross product that is zero: its sign", true},
                                {"dSqrt(|x|), as the shaders take roots", true}};
    std::mt19937_64 rng(77);
    std::uniform_real_distribution<double> u(-2000.0, 2000.0);
    std::vector<Vec2> in(4096);
    for (Vec2& p : in) p = {u(rng), u(rng) * 1e-3};
    in[0] = {1.0 / 3.0, 2.0 / 3.0};
    in[1] = {1000.0000018057766, 1099.9999986812238}; // poly2's case 9 on the H100
    in[2] = {-1.0, 0.0}; // zeros' signs: (-1)(+0), -0 - +0, 1 (-0)
    in[3] = {-0.0, 0.0};
    in[4] = {1.0, -0.0};
    const Program program = buildProgram({"doubles_test.comp"}, shaderSource("doubles.glsl"));
    const Buffer inBuf(in.size() * sizeof(Vec2), in.data());
    const Buffer scalarBuf(in.size() * sizeof(Vec2), in.data());
    std::vector<int32_t> index(in.size()); // i -> 7 i mod n: a permutation (n = 4096)
    for (size_t i = 0; i < in.size(); ++i) index[i] = int32_t(i * 7 % in.size());
    const Buffer indexBuf(index.size() * sizeof(int32_t), index.data());
    const Buffer outBuf(in.size() * kPaths * 2 * sizeof(uint32_t), nullptr, GL_MAP_READ_BIT);
    program.use();
    glProgramUniform1ui(program.id(), program.uniform("uCount"), GLuint(in.size()));
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 0, inBuf.id());
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 1, scalarBuf.id());
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 2, outBuf.id());
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 3, indexBuf.id());
    glDispatchCompute(GLuint((in.size() + 15) / 16), 1, 1);
    glMemoryBarrier(GL_BUFFER_UPDATE_BARRIER_BIT);
    std::vector<double> out(in.size() * kPaths);
    glGetNamedBufferSubData(outBuf.id(), 0, GLsizeiptr(out.size() * sizeof(double)), out.data());
    glUseProgram(0);
    checkGlError("doubles_test.comp");
    size_t bad[kPaths] = {};
    for (size_t i = 0; i < in.size(); ++i) {
        const double x = in[i].x, y = in[i].y;
        volatile double d = x - y, m = x * y; // volatile: no fma, as the shader's precise
        volatile double c1 = (x - 1.0) * (y + 1.0), c2 = (y - 1.0) * (x + 1.0);
        // poly2Cross((1, -1), (-1, -1), (x, y)) = (-2) (y + 1) - 0 (x - 1)
        volatile double e1 = -2.0 * (y - -1.0), e2 = 0.0 * (x - 1.0);
        const double cross = e1 - e2;
        volatile double q = x / y, r = std::sqrt(std::abs(x));
        volatile double z1 = (-1.0 - x) * (y - y), z2 = (2.0 - y) * (x - x); // poly2Cross(p, (-1, 2), p)
        const double zeroCross = z1 - z2;
        const double want[kPaths] = {x, y, x, x, x, x, d, m, c1 - c2, cross, cross, in[size_t(index[i])].x,
                                     x, x, x, x, x, x, std::ldexp(x, int(i % 16 % 3)), x, x, x, x, q, r, q, r, zeroCross, r};
        for (int k = 0; k < kPaths; ++k) {
            const double got = out[i * kPaths + k];
            if (bitsOf(got) == bitsOf(want[k]) || (std::isnan(got) && std::isnan(want[k]))) continue;
            if (k == kPlainCross && std::abs(got - want[k]) <= 4 * std::numeric_limits<double>::epsilon() * std::abs(want[k]))
                continue;
            if (++bad[k] <= 2 && paths[k].must)
                ADD_FAILURE() << paths[k].name << ", input " << i << ": shader " << std::hexfloat << got << " want "
                              << want[k] << std::defaultfloat;
        }
    }
    for (int k = 0; k < kPaths; ++k) {
        if (paths[k].must)
            EXPECT_EQ(bad[k], 0u) << paths[k].name << ": of " << in.size();
        else if (bad[k] != 0)
            std::printf("this driver changes %zu of %zu doubles kept as \"%s\" (the shaders keep none so)\n", bad[k],
                        in.size(), paths[k].name);
    }
}

TEST(RenderPoly2, ShaderDecidesAsTheCpuBitForBit)
{
    MTCUT_REQUIRE_GL();
    std::vector<Input> inputs;
    Gen g(20240611);
    for (int i = 0; i < 4000; ++i) inputs.push_back(segmentCase(g));
    for (int i = 0; i < 4000; ++i) inputs.push_back(triangleCase(g));
    for (int i = 0; i < 2000; ++i) inputs.push_back(polygonCase(g, kArea, 3, 40));
    for (int i = 0; i < 4000; ++i) inputs.push_back(polygonCase(g, kBest, 3, int(kBestOfAllMax)));
    for (int i = 0; i < 200; ++i) inputs.push_back(polygonCase(g, kBest, int(kBestOfAllMax) + 1, 12));
    for (int i = 0; i < 3000; ++i) inputs.push_back(polygonCase(g, kEarClip, 3, i % 3 == 0 ? 40 : 12));
    for (int i = 0; i < 2000; ++i) inputs.push_back(bridgeCase(g));
    for (Input& in : overflowCases()) inputs.push_back(std::move(in));
    // The unit tests' hard cases too: a crack bridged to the copy facing it.
    Input crack;
    crack.func = kBridge;
    crack.pts = {{59.7836456654, 60.4113036488}, {60.63203734, 59.6629485626}, {60.63203734, 60.9363385125},
                 {60.2394047612, 60.2156341509}, {60.447380912, 60.0909334751}, {60.5844215691, 60.1344726631},
                 {60.447380912, 60.0909334751}};
    crack.poly = {0, 1, 2};
    crack.holes = {{4, 5, 6, 3}};
    crack.kind = "crack";
    inputs.push_back(crack);

    double compileMs = 0, runMs = 0;
    const std::vector<uint32_t> records = runShader(inputs, compileMs, runMs);
    ASSERT_EQ(records.size(), inputs.size() * kRecord);

    size_t count[kFuncCount] = {}, trueCount[kFuncCount] = {}, overflowCount[kFuncCount] = {}, tris[kFuncCount] = {};
    size_t mismatches = 0, mismatchCount[kFuncCount] = {}, zeroSigns = 0;
    struct Tally
    {
        size_t outcome = 0, value[4] = {}, zeroSign[4] = {}, oneUlp[4] = {};
        uint64_t maxUlps[4] = {};
    };
    Tally tally[kFuncCount];
    for (size_t i = 0; i < inputs.size(); ++i) {
        const Answer cpu = cpuAnswer(inputs[i]), gpu = gpuAnswer(records.data() + i * kRecord);
        const int f = inputs[i].func;
        ++count[f];
        trueCount[f] += cpu.r0 && !cpu.overflow;
        overflowCount[f] += cpu.overflow;
        tris[f] += cpu.overflow ? 0 : cpu.tris.size() / 3;
        for (int k = 0; k < 4; ++k) zeroSigns += cpu.bits[k] != gpu.bits[k] && sameZero(cpu.bits[k], gpu.bits[k]);
        const std::string d = difference(cpu, gpu);
        if (d.empty()) continue;
        ++mismatches;
        if (++mismatchCount[f] <= 3) // the first few of each function
            ADD_FAILURE() << "case " << i << ":" << d << "\n  " << inputText(inputs[i]);
        if (cpu.overflow) continue;
        // What differs, to tell a driver's rounding from a sign of zero.
        Tally& t = tally[f];
        t.outcome += cpu.r0 != gpu.r0 || cpu.r1 != gpu.r1 || cpu.tris != gpu.tris || cpu.poly != gpu.poly;
        for (int k = 0; k < 4; ++k) {
            if (cpu.bits[k] == gpu.bits[k]) continue;
            ++t.value[k];
            if (doubleOf(cpu.bits[k]) == 0.0 && doubleOf(gpu.bits[k]) == 0.0) {
                ++t.zeroSign[k];
            } else if ((cpu.bits[k] >> 63) == (gpu.bits[k] >> 63)) {
                const uint64_t ulps = cpu.bits[k] > gpu.bits[k] ? cpu.bits[k] - gpu.bits[k] : gpu.bits[k] - cpu.bits[k];
                t.oneUlp[k] += ulps == 1;
                t.maxUlps[k] = std::max(t.maxUlps[k], ulps);
            } else {
                t.maxUlps[k] = UINT64_MAX; // opposite signs
            }
        }
    }
    for (int f = 0; f < kFuncCount; ++f) {
        const Tally& t = tally[f];
        if (mismatchCount[f] == 0) continue;
        std::printf("%s: the outcome (bools, triangles, polygon) differs in %zu;", kFuncNames[f], t.outcome);
        for (int k = 0; k < 4; ++k)
            if (t.value[k])
                std::printf(" double %d in %zu (%zu only the sign of zero, %zu by 1 ulp, at most %llu ulp);", k,
                            t.value[k], t.zeroSign[k], t.oneUlp[k], (unsigned long long)t.maxUlps[k]);
        std::printf("\n");
    }
    std::printf("zeros of the other sign (not differences): %zu\n", zeroSigns);
    EXPECT_EQ(mismatches, 0u) << "cases where the shader differs from the C++";
    for (int f = 0; f < kFuncCount; ++f) {
        std::printf("%-30s %5zu cases, %5zu true, %3zu over capacity, %6zu triangles, %5zu differ\n", kFuncNames[f],
                    count[f], trueCount[f], overflowCount[f], tris[f], mismatchCount[f]);
        // Both outcomes occur (the bool of minSine's case is same2's).
        if (f == kArea) continue;
        EXPECT_GT(trueCount[f], count[f] / 50) << kFuncNames[f];
        EXPECT_LT(trueCount[f], count[f]) << kFuncNames[f];
    }
    EXPECT_EQ(overflowCount[kEarClip], 2u);
    EXPECT_EQ(overflowCount[kBest], 1u);
    EXPECT_EQ(overflowCount[kBridge], 2u);
    std::printf("%zu cases: shader compiled in %.0f ms, ran in %.0f ms\n", inputs.size(), compileMs, runMs);
}
