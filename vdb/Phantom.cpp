#include "vdb/Phantom.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <limits>
#include <string>
#include <vector>

namespace mtcut::vdb {

using openvdb::Vec3d;

namespace {

// ---------------------------------------------------------------- HU values
constexpr float kAir = -1000.0f;
constexpr float kFat = -95.0f;
constexpr float kSkin = 40.0f;
constexpr float kMuscle = 45.0f;
constexpr float kBrain = 32.0f;
constexpr float kCsf = 10.0f;
constexpr float kEye = 15.0f;
constexpr float kDisc = 85.0f;
constexpr float kCortex = 1600.0f;      // outer table of the vault
constexpr float kInnerTable = 1500.0f;
constexpr float kCortexThin = 1300.0f;  // facial bones, vertebrae
constexpr float kCancellous = 480.0f;   // diploe, cancellous bone
constexpr float kDentin = 1700.0f;
constexpr float kEnamel = 2700.0f;

// Field of view (mm), centred on the world origin.
const Vec3d kFov(240.0, 240.0, 256.0);

// ---------------------------------------------------------------- geometry
inline double length2(double x, double y) { return std::sqrt(x * x + y * y); } // no overflow care needed

struct Box
{
    Vec3d lo{std::numeric_limits<double>::max()};
    Vec3d hi{std::numeric_limits<double>::lowest()};
    void expand(const Vec3d& p)
    {
        for (int a = 0; a < 3; ++a) {
            lo[a] = std::min(lo[a], p[a]);
            hi[a] = std::max(hi[a], p[a]);
        }
    }
    void expand(const Box& b)
    {
        expand(b.lo);
        expand(b.hi);
    }
    Box padded(double r) const { return Box{lo - Vec3d(r), hi + Vec3d(r)}; }
    /// Distance from p to the box (0 inside).
    double distance(const Vec3d& p) const
    {
        double s = 0.0;
        for (int a = 0; a < 3; ++a) {
            const double e = std::max({lo[a] - p[a], 0.0, p[a] - hi[a]});
            s += e * e;
        }
        return std::sqrt(s);
    }
};

/// A solid as a signed distance (mm; negative inside). Exact for capsules,
/// boxes, tori and sweeps; the usual first-order approximation for ellipsoids
/// (exact on the surface, within a few percent a few mm away for these
/// shapes). Optional: clip planes (intersection with half-spaces), cut-outs
/// (subtraction) and a smooth union with other shapes.
struct Shape
{
    enum class Kind { Ellipsoid, Capsule, RoundBox, Torus, Sweep };
    Kind kind = Kind::Ellipsoid;
    Vec3d center{0.0};     // Ellipsoid, RoundBox, Torus
    Vec3d size{1.0};       // Ellipsoid radii; RoundBox half extents (rounding included)
    Vec3d a{0.0}, b{0.0};  // Capsule ends
    double radius = 0.0;   // Capsule radius; RoundBox / Sweep rounding; Torus tube radius
    double major = 0.0;    // Torus ring radius (axis z)
    openvdb::Mat3d toLocal = openvdb::Mat3d::identity(); // RoundBox: world -> box axes (rows)
    std::vector<openvdb::Vec2d> path; // Sweep: polyline in the xy plane
    double sweepZ = 0.0;              // Sweep: centre z
    double halfWidth = 0.0, halfHeight = 0.0; // Sweep cross-section (rounding included)

    struct Plane
    {
        Vec3d normal; // unit, pointing out of the kept side
        Vec3d point;
    };
    std::vector<Plane> clips;
    std::vector<Shape> cuts;
    std::vector<Shape> unions;
    double blend = 0.0; // smooth-union radius, mm

    double distance(const Vec3d& p) const
    {
        double d = baseDistance(p);
        if (!unions.empty()) {
            for (const Shape& s : unions) {
                // A shape whose box is further than d + blend cannot change the result.
                if (s.box().distance(p) >= d + blend) continue;
                const double e = s.distance(p);
                const double h = std::max(blend - std::abs(d - e), 0.0) / blend;
                d = std::min(d, e) - h * h * blend * 0.25;
            }
        }
        for (const Plane& c : clips) d = std::max(d, c.normal.dot(p - c.point));
        for (const Shape& c : cuts) {
            if (c.box().distance(p) >= -d) continue; // then -c.distance(p) <= d
            d = std::max(d, -c.distance(p));
        }
        return d;
    }

    double baseDistance(const Vec3d& p) const
    {
        switch (kind) {
        case Kind::Ellipsoid: {
            const Vec3d q = p - center;
            const Vec3d q1(q.x() / size.x(), q.y() / size.y(), q.z() / size.z());
            const Vec3d q2(q1.x() / size.x(), q1.y() / size.y(), q1.z() / size.z());
            const double k0 = q1.length(), k1 = q2.length();
            if (k1 < 1e-12) return -std::min({size.x(), size.y(), size.z()});
            return k0 * (k0 - 1.0) / k1;
        }
        case Kind::Capsule: {
            const Vec3d pa = p - a, ba = b - a;
            const double h = std::clamp(pa.dot(ba) / ba.dot(ba), 0.0, 1.0);
            return (pa - ba * h).length() - radius;
        }
        case Kind::RoundBox: {
            const Vec3d q = toLocal * (p - center);
            const Vec3d e(std::abs(q.x()) - size.x() + radius, std::abs(q.y()) - size.y() + radius,
                          std::abs(q.z()) - size.z() + radius);
            const Vec3d pos(std::max(e.x(), 0.0), std::max(e.y(), 0.0), std::max(e.z(), 0.0));
            return pos.length() + std::min(std::max({e.x(), e.y(), e.z()}), 0.0) - radius;
        }
        case Kind::Torus: {
            const Vec3d q = p - center;
            const double r = length2(q.x(), q.y()) - major;
            return length2(r, q.z()) - radius;
        }
        case Kind::Sweep: {
            double best = std::numeric_limits<double>::max();
            const openvdb::Vec2d xy(p.x(), p.y());
            for (size_t s = 0; s + 1 < path.size(); ++s) {
                const openvdb::Vec2d pa = xy - path[s], ba = path[s + 1] - path[s];
                const double h = std::clamp(pa.dot(ba) / ba.dot(ba), 0.0, 1.0);
                best = std::min(best, (pa - ba * h).lengthSqr());
            }
            const double ex = std::sqrt(best) - halfWidth + radius;
            const double ez = std::abs(p.z() - sweepZ) - halfHeight + radius;
            return length2(std::max(ex, 0.0), std::max(ez, 0.0)) + std::min(std::max(ex, ez), 0.0) -
                   radius;
        }
        }
        return 0.0;
    }

    /// Bounds of the solid (the smooth union may grow it by blend / 4).
    Box box() const { return mBox; }

    void finish()
    {
        for (Shape& s : unions) s.finish();
        for (Shape& s : cuts) s.finish();
        Box bx;
        switch (kind) {
        case Kind::Ellipsoid: bx = Box{center - size, center + size}; break;
        case Kind::Capsule:
            bx.expand(a);
            bx.expand(b);
            bx = bx.padded(radius);
            break;
        case Kind::RoundBox: {
            const openvdb::Mat3d toWorld = toLocal.transpose();
            for (int c = 0; c < 8; ++c) {
                const Vec3d corner((c & 1 ? 1 : -1) * size.x(), (c & 2 ? 1 : -1) * size.y(),
                                   (c & 4 ? 1 : -1) * size.z());
                bx.expand(center + toWorld * corner);
            }
            break;
        }
        case Kind::Torus: {
            const double r = major + radius;
            bx = Box{center - Vec3d(r, r, radius), center + Vec3d(r, r, radius)};
            break;
        }
        case Kind::Sweep:
            for (const auto& q : path) bx.expand(Vec3d(q.x(), q.y(), sweepZ));
            bx.lo -= Vec3d(halfWidth, halfWidth, halfHeight);
            bx.hi += Vec3d(halfWidth, halfWidth, halfHeight);
            break;
        }
        for (const Shape& s : unions) bx.expand(s.box());
        if (!unions.empty()) bx = bx.padded(blend * 0.25);
        mBox = bx;
    }

private:
    Box mBox;
};

Shape ellipsoid(const Vec3d& c, const Vec3d& r)
{
    Shape s;
    s.kind = Shape::Kind::Ellipsoid;
    s.center = c;
    s.size = r;
    return s;
}

Shape capsule(const Vec3d& a, const Vec3d& b, double r)
{
    Shape s;
    s.kind = Shape::Kind::Capsule;
    s.a = a;
    s.b = b;
    s.radius = r;
    return s;
}

Shape roundBox(const Vec3d& c, const Vec3d& half, double rounding)
{
    Shape s;
    s.kind = Shape::Kind::RoundBox;
    s.center = c;
    s.size = half;
    s.radius = rounding;
    return s;
}

/// A flat rounded box from `from` to `to` (its long axis), `halfWidth` across in
/// the direction closest to world +y, `halfThickness` in the third direction.
Shape plate(const Vec3d& from, const Vec3d& to, double halfWidth, double halfThickness, double rounding)
{
    const Vec3d u = (to - from).unitSafe();
    const Vec3d v = (Vec3d(0, 1, 0) - u * u.y()).unitSafe();
    const Vec3d w = u.cross(v);
    Shape s = roundBox((from + to) * 0.5, Vec3d(halfThickness, halfWidth, (to - from).length() * 0.5), rounding);
    s.toLocal = openvdb::Mat3d(w.x(), w.y(), w.z(), v.x(), v.y(), v.z(), u.x(), u.y(), u.z());
    return s;
}

Shape torusZ(const Vec3d& c, double major, double tube)
{
    Shape s;
    s.kind = Shape::Kind::Torus;
    s.center = c;
    s.major = major;
    s.radius = tube;
    return s;
}

Shape sweep(std::vector<openvdb::Vec2d> path, double z, double halfWidth, double halfHeight, double rounding)
{
    Shape s;
    s.kind = Shape::Kind::Sweep;
    s.path = std::move(path);
    s.sweepZ = z;
    s.halfWidth = halfWidth;
    s.halfHeight = halfHeight;
    s.radius = rounding;
    return s;
}

Vec3d mirrorX(const Vec3d& p) { return Vec3d(-p.x(), p.y(), p.z()); }

// ---------------------------------------------------------------- anatomy
// A dental arch: half an ellipse in the xy plane, x = A sin(phi),
// y = yc - B cos(phi), |phi| <= phiMax (incisors at phi = 0, the front, -y).
struct Arch
{
    double A, B, yc, phiMax;
    openvdb::Vec2d at(double phi) const { return {A * std::sin(phi), yc - B * std::cos(phi)}; }
    std::vector<openvdb::Vec2d> polyline(int n) const
    {
        std::vector<openvdb::Vec2d> pts;
        for (int s = 0; s <= n; ++s) pts.push_back(at(-phiMax + 2.0 * phiMax * s / n));
        return pts;
    }
    /// Tooth t of kTeeth, left to right (-x first).
    openvdb::Vec2d tooth(int t) const { return at(-phiMax + 2.0 * phiMax * (t + 0.5) / kTeeth); }
    static constexpr int kTeeth = 14;
};

constexpr double kPi = 3.14159265358979323846;
const Arch kUpperArch{28.0, 40.0, -45.0, 100.0 * kPi / 180.0};
const Arch kLowerArch{26.0, 37.0, -45.0, 100.0 * kPi / 180.0};

/// Crown radius (mm) of tooth t: incisors small, molars large.
double toothRadius(int t)
{
    const int fromMiddle = std::min(t, Arch::kTeeth - 1 - t); // 0 = last molar, 6 = central incisor
    static const double r[7] = {4.6, 4.6, 4.4, 3.8, 3.6, 3.3, 3.1};
    return r[fromMiddle];
}

// Cranial vault: ellipsoid cut by a sloping skull base.
const Vec3d kCraniumCenter(0.0, 5.0, 38.0);
const Vec3d kCraniumRadii(74.0, 90.0, 72.0);
constexpr double kUpperCrownZ = -46.0, kLowerCrownZ = -59.5, kCrownHalfHeight = 4.5;
constexpr double kFirstVertebraZ = -30.0, kVertebraStep = 15.0, kVertebraHalfHeight = 6.0;
constexpr int kVertebrae = 7;
const Vec3d kOrbit(32.0, -64.0, 16.0);

struct Band
{
    double offset; // the band holds d < offset (mm)
    float hu;
};

struct Layer
{
    Shape shape;
    std::vector<Band> bands; // decreasing offsets: outermost first
    Box bounds;              // where the layer can change a value (blur included)
};

struct Anatomy
{
    std::vector<Layer> layers;
    double blurWidth = 1.0; // mm

    void add(Shape shape, std::vector<Band> bands)
    {
        shape.finish();
        Layer layer{std::move(shape), std::move(bands), {}};
        layer.bounds = layer.shape.box().padded(std::max(0.0, layer.bands.front().offset) + blurWidth);
        layers.push_back(std::move(layer));
    }
    void add(Shape shape, float hu) { add(std::move(shape), {{0.0, hu}}); }
};

Shape cranium()
{
    Shape s = ellipsoid(kCraniumCenter, kCraniumRadii);
    // Skull base: z >= 8 - 0.283 (y + 60), higher in front (anterior fossa).
    const double slope = 34.0 / 120.0;
    s.clips.push_back({Vec3d(0.0, -slope, -1.0).unitSafe(), Vec3d(0.0, -60.0, 8.0)});
    return s;
}

Anatomy buildAnatomy(double blurWidth)
{
    Anatomy an;
    an.blurWidth = blurWidth;
    const std::vector<openvdb::Vec2d> lowerPath = [] {
        std::vector<openvdb::Vec2d> p{{-46.0, -8.0}};
        for (const auto& q : kLowerArch.polyline(16)) p.push_back(q);
        p.push_back({46.0, -8.0});
        return p;
    }();
    const double mandibleZ = -72.0, mandibleHalfH = 12.0, mandibleHalfW = 6.5;

    // Soft tissue envelope: skin, subcutaneous fat, muscle.
    {
        Shape env = ellipsoid(kCraniumCenter, kCraniumRadii + Vec3d(6.0));
        env.unions.push_back(ellipsoid(Vec3d(0.0, -50.0, -30.0), Vec3d(64.0, 48.0, 62.0))); // face
        env.unions.push_back(ellipsoid(Vec3d(0.0, -62.0, 14.0), Vec3d(58.0, 32.0, 22.0)));  // brows, eyes
        env.unions.push_back(capsule(Vec3d(0.0, -92.0, 20.0), Vec3d(0.0, -102.0, -10.0), 8.0)); // nose
        env.unions.push_back(sweep(lowerPath, mandibleZ, mandibleHalfW + 8.0, mandibleHalfH + 7.0, 6.0)); // jaw
        env.unions.push_back(capsule(Vec3d(0.0, 12.0, -160.0), Vec3d(0.0, 12.0, -25.0), 62.0)); // neck
        env.blend = 12.0;
        an.add(std::move(env), {{0.0, kSkin}, {-2.0, kFat}, {-6.0, kMuscle}});
    }
    // Cranial vault: outer table, diploe, inner table, CSF, brain.
    an.add(cranium(), {{0.0, kCortex}, {-2.5, kCancellous}, {-5.5, kInnerTable}, {-7.5, kCsf}, {-9.5, kBrain}});
    for (const Vec3d& c : {Vec3d(12.0, 5.0, 50.0), Vec3d(-12.0, 5.0, 50.0)}) // lateral ventricles
        an.add(ellipsoid(c, Vec3d(5.0, 22.0, 9.0)), kCsf);
    // Brow ridge with the frontal sinus.
    an.add(ellipsoid(Vec3d(0.0, -80.0, 40.0), Vec3d(17.0, 8.0, 13.0)), {{0.0, kCortexThin}, {-2.0, kCancellous}});
    an.add(ellipsoid(Vec3d(0.0, -80.0, 40.0), Vec3d(13.0, 4.5, 9.0)), kAir);
    // Spinal cord (CSF and cord), through the skull base: the foramen magnum.
    an.add(capsule(Vec3d(0.0, 30.0, -140.0), Vec3d(0.0, 30.0, -6.0), 6.0), kCsf);

    // Orbits: bony wall, fat, globe; open at the front.
    const Shape::Plane orbitFront{Vec3d(0.0, -1.0, 0.0), Vec3d(0.0, -80.0, 0.0)};
    for (const Vec3d& c : {kOrbit, mirrorX(kOrbit)}) {
        Shape wall = ellipsoid(c, Vec3d(19.5, 23.5, 18.5));
        wall.clips.push_back(orbitFront);
        an.add(std::move(wall), kCortexThin);
        Shape fat = ellipsoid(c, Vec3d(17.0, 21.0, 16.0));
        fat.clips.push_back({Vec3d(0.0, -1.0, 0.0), Vec3d(0.0, -90.0, 0.0)});
        an.add(std::move(fat), kFat);
        an.add(ellipsoid(c + Vec3d(0.0, -12.0, -2.0), Vec3d(12.0)), kEye);
    }
    // Zygomatic bones and arches.
    for (double sx : {1.0, -1.0}) {
        an.add(capsule(Vec3d(30.0 * sx, -70.0, -4.0), Vec3d(54.0 * sx, -55.0, 4.0), 5.0),
               {{0.0, kCortexThin}, {-2.0, kCancellous}});
        an.add(capsule(Vec3d(54.0 * sx, -55.0, 4.0), Vec3d(66.0 * sx, 0.0, 4.0), 3.0), kCortexThin);
    }

    // Maxilla with sinuses, nasal cavity and septum, upper alveolar ridge.
    an.add(roundBox(Vec3d(0.0, -68.0, -16.0), Vec3d(34.0, 26.0, 16.0), 8.0), {{0.0, kCortexThin}, {-2.0, kCancellous}});
    an.add(sweep(kUpperArch.polyline(16), -36.0, 7.0, 7.0, 3.0), {{0.0, kCortexThin}, {-2.0, kCancellous}});
    for (double sx : {1.0, -1.0})
        an.add(ellipsoid(Vec3d(19.0 * sx, -68.0, -14.0), Vec3d(10.0, 15.0, 11.0)), kAir);
    an.add(roundBox(Vec3d(0.0, -70.0, -12.0), Vec3d(6.0, 24.0, 14.0), 2.0), kAir);
    an.add(roundBox(Vec3d(0.0, -72.0, -12.0), Vec3d(0.6, 20.0, 16.0), 0.5), kCortexThin);
    // Nasal bones: from the frontal bone to the maxilla beside the nasal aperture.
    for (double sx : {1.0, -1.0})
        an.add(capsule(Vec3d(4.0 * sx, -86.0, 30.0), Vec3d(9.5 * sx, -91.0, -4.0), 3.0), kCortexThin);
    // Airway: nasopharynx and pharynx, in front of the vertebrae.
    an.add(capsule(Vec3d(0.0, -40.0, -12.0), Vec3d(0.0, -12.0, -30.0), 7.0), kAir);
    an.add(capsule(Vec3d(0.0, -12.0, -30.0), Vec3d(0.0, -12.0, -140.0), 8.0), kAir);

    // Mandible: body along the lower arch, rami, condyles.
    an.add(sweep(lowerPath, mandibleZ, mandibleHalfW, mandibleHalfH, 3.0), {{0.0, kCortex}, {-2.5, kCancellous}});
    for (double sx : {1.0, -1.0}) {
        an.add(plate(Vec3d(46.0 * sx, -8.0, -80.0), Vec3d(50.0 * sx, 6.0, -24.0), 13.0, 3.5, 2.0),
               {{0.0, kCortex}, {-2.0, kCancellous}});
        an.add(ellipsoid(Vec3d(50.0 * sx, 6.0, -22.0), Vec3d(10.0, 5.0, 5.0)), {{0.0, kCortex}, {-2.0, kCancellous}});
    }

    // Teeth: dentin roots in bone, enamel crowns.
    for (int t = 0; t < Arch::kTeeth; ++t) {
        const double r = toothRadius(t);
        const auto u = kUpperArch.tooth(t), l = kLowerArch.tooth(t);
        an.add(capsule(Vec3d(u.x(), u.y(), -28.0), Vec3d(u.x(), u.y(), kUpperCrownZ), 0.7 * r), kDentin);
        an.add(ellipsoid(Vec3d(u.x(), u.y(), kUpperCrownZ), Vec3d(r, r, kCrownHalfHeight)), kEnamel);
        an.add(capsule(Vec3d(l.x(), l.y(), -76.0), Vec3d(l.x(), l.y(), kLowerCrownZ), 0.7 * r), kDentin);
        an.add(ellipsoid(Vec3d(l.x(), l.y(), kLowerCrownZ), Vec3d(r, r, kCrownHalfHeight)), kEnamel);
    }

    // Cervical vertebrae with discs.
    for (int v = 0; v < kVertebrae; ++v) {
        const double z = kFirstVertebraZ - kVertebraStep * v;
        const std::vector<Band> bone{{0.0, kCortexThin}, {-1.8, kCancellous}};
        an.add(roundBox(Vec3d(0.0, 14.0, z), Vec3d(9.0, 8.0, kVertebraHalfHeight), 3.0), bone);
        an.add(torusZ(Vec3d(0.0, 30.0, z), 10.0, 3.0), bone);
        an.add(capsule(Vec3d(0.0, 42.0, z), Vec3d(0.0, 55.0, z - 5.0), 3.0), bone);
        for (double sx : {1.0, -1.0})
            an.add(capsule(Vec3d(9.0 * sx, 22.0, z), Vec3d(24.0 * sx, 24.0, z), 3.0), bone);
        const double discHalf = 0.5 * kVertebraStep - kVertebraHalfHeight + 0.5;
        if (v + 1 < kVertebrae)
            an.add(roundBox(Vec3d(0.0, 14.0, z - 0.5 * kVertebraStep), Vec3d(8.5, 7.5, discHalf), 1.0), kDisc);
    }
    return an;
}

// ---------------------------------------------------------------- noise
inline uint64_t mix64(uint64_t x)
{
    x ^= x >> 30;
    x *= 0xbf58476d1ce4e5b9ULL;
    x ^= x >> 27;
    x *= 0x94d049bb133111ebULL;
    x ^= x >> 31;
    return x;
}

/// Irwin-Hall(4) variate times kNoiseScale: centred, |n| <= 2 * 65535, a
/// pure function of (i, j, k, seed).
inline int32_t noiseSample(int i, int j, int k, uint32_t seed)
{
    const uint64_t key = (uint64_t(uint32_t(i)) | (uint64_t(uint32_t(j)) << 21) | (uint64_t(uint32_t(k)) << 42)) ^
                         (uint64_t(seed) * 0x9e3779b97f4a7c15ULL);
    const uint64_t h = mix64(key + 0x632be59bd9b4e019ULL);
    // Four terms uniform on {0..65535}: mean 4 * 32767.5 = 131070.
    return int32_t((h & 0xffff) + ((h >> 16) & 0xffff) + ((h >> 32) & 0xffff) + (h >> 48)) - 131070;
}
/// Standard deviation of noiseSample: sqrt(4 (65536^2 - 1) / 12).
const double kNoiseSd = std::sqrt(4.0 * (65536.0 * 65536.0 - 1.0) / 12.0);

// Marching steps use this fraction of the distance: the ellipsoid distance is
// approximate (its gradient can exceed 1 slightly), the others are exact.
constexpr double kMarchSafety = 0.8;

inline float smoothCoverage(double d, double invWidth)
{
    const double t = std::clamp(0.5 - d * invWidth, 0.0, 1.0);
    return float(t * t * (3.0 - 2.0 * t));
}

} // namespace

Vec3d phantomFieldOfView() { return kFov; }

PhantomLandmarks phantomLandmarks()
{
    PhantomLandmarks l;
    l.outsideHead = Vec3d(100.0, -100.0, 100.0);
    l.brain = Vec3d(0.0, 10.0, 70.0);
    l.skullLateral = kCraniumCenter + Vec3d(kCraniumRadii.x() - 1.25, 0.0, 0.0);
    l.vertexBone = kCraniumCenter + Vec3d(0.0, 0.0, kCraniumRadii.z() - 1.25);
    l.skullTopZ = kCraniumCenter.z() + kCraniumRadii.z();
    l.maxillarySinus = Vec3d(19.0, -68.0, -14.0);
    l.maxillaBone = Vec3d(3.0, -68.0, -29.0);
    const int centralLeft = Arch::kTeeth / 2, lastLeft = Arch::kTeeth - 1;
    const auto ui = kUpperArch.tooth(centralLeft), um = kUpperArch.tooth(lastLeft);
    const auto li = kLowerArch.tooth(centralLeft);
    l.upperIncisorCrown = Vec3d(ui.x(), ui.y(), kUpperCrownZ);
    l.upperMolarCrown = Vec3d(um.x(), um.y(), kUpperCrownZ);
    l.lowerIncisorCrown = Vec3d(li.x(), li.y(), kLowerCrownZ);
    // Mandible body between the last lower molar and the angle: no tooth nearby.
    const auto archEnd = kLowerArch.at(kLowerArch.phiMax);
    l.mandibleBone = Vec3d(0.5 * (archEnd.x() + 46.0), 0.5 * (archEnd.y() - 8.0), -72.0);
    for (int v = 0; v < kVertebrae; ++v) l.vertebraBodies.push_back(Vec3d(0.0, 14.0, kFirstVertebraZ - kVertebraStep * v));
    l.vertebraBody = l.vertebraBodies[2];
    l.upperCrownBottomZ = kUpperCrownZ - kCrownHalfHeight;
    l.lowerCrownTopZ = kLowerCrownZ + kCrownHalfHeight;
    l.leFortZ = -20.0;
    return l;
}

DenseScan makePhantomScan(const PhantomOptions& options, Interrupter* interrupter)
{
    checkDims(options.dims, "phantom");
    if (!(options.noiseSigma >= 0.0f) || !std::isfinite(options.noiseSigma)) {
        throw InputError("phantom: noise sigma " + std::to_string(options.noiseSigma) +
                         " HU must be finite and >= 0");
    }
    InterrupterScope scope(interrupter, "phantom");
    const openvdb::Coord dims = options.dims;
    const Vec3d spacing(kFov.x() / dims.x(), kFov.y() / dims.y(), kFov.z() / dims.z());
    const Vec3d origin = kFov * -0.5 + spacing * 0.5;

    DenseScan scan;
    scan.geometry.dims = dims;
    scan.geometry.spacing = spacing;
    scan.geometry.origin = origin;
    scan.units = "HU";
    const size_t nx = size_t(dims.x()), ny = size_t(dims.y()), nz = size_t(dims.z());
    scan.values.resize(nx * ny * nz);

    // Partial volume: each boundary is a smooth step as wide as a voxel (rms of the spacing).
    const double blurWidth = std::sqrt((spacing.lengthSqr()) / 3.0);
    const Anatomy an = buildAnatomy(blurWidth);
    const double invWidth = 1.0 / blurWidth, halfWidth = 0.5 * blurWidth;
    const float noiseScale = float(options.noiseSigma / kNoiseSd);
    const uint32_t seed = options.seed;

    std::atomic<bool> cancelled{false};
    std::atomic<int> slicesDone{0};
    float* out = scan.values.data();
    tbb::parallel_for(tbb::blocked_range<size_t>(0, nz, 1), [&](const tbb::blocked_range<size_t>& r) {
        std::vector<const Layer*> inSlice, inRow;
        inSlice.reserve(an.layers.size());
        inRow.reserve(an.layers.size());
        for (size_t k = r.begin(); k != r.end(); ++k) {
            if (cancelled) return;
            if (interrupter && interrupter->wasInterrupted(int(100 * slicesDone.load() / nz))) {
                cancelled = true;
                return;
            }
            const double z = origin.z() + spacing.z() * double(k);
            inSlice.clear();
            for (const Layer& l : an.layers)
                if (z >= l.bounds.lo.z() && z <= l.bounds.hi.z()) inSlice.push_back(&l);
            for (size_t j = 0; j < ny; ++j) {
                const double y = origin.y() + spacing.y() * double(j);
                float* row = out + (k * ny + j) * nx;
                std::fill(row, row + nx, kAir);
                for (const Layer* l : inSlice) {
                    if (y < l->bounds.lo.y() || y > l->bounds.hi.y()) continue;
                    const double fi0 = std::ceil((l->bounds.lo.x() - origin.x()) / spacing.x());
                    const double fi1 = std::floor((l->bounds.hi.x() - origin.x()) / spacing.x());
                    const size_t i0 = size_t(std::max(fi0, 0.0));
                    const size_t i1 = size_t(std::min(fi1, double(nx) - 1.0));
                    if (fi1 < 0.0 || fi0 > double(nx) - 1.0) continue;
                    // March along the row: where the shape is further than half a blur width
                    // from every band boundary, the distance bounds how far the row stays
                    // outside (unchanged) or inside (the innermost value); skip that far.
                    const double outer = l->bands.front().offset + halfWidth;
                    const double inner = l->bands.back().offset - halfWidth;
                    const float innerHu = l->bands.back().hu;
                    size_t i = i0;
                    while (i <= i1) {
                        const Vec3d p(origin.x() + spacing.x() * double(i), y, z);
                        const double d = l->shape.distance(p);
                        if (d >= outer) {
                            i += 1 + size_t(kMarchSafety * (d - outer) / spacing.x());
                            continue;
                        }
                        if (d <= inner) {
                            const size_t end = std::min(i1, i + size_t(kMarchSafety * (inner - d) / spacing.x()));
                            std::fill(row + i, row + end + 1, innerHu);
                            i = end + 1;
                            continue;
                        }
                        float v = row[i];
                        for (const Band& b : l->bands) {
                            const float c = smoothCoverage(d - b.offset, invWidth);
                            if (c <= 0.0f) break;
                            v += (b.hu - v) * c;
                        }
                        row[i] = v;
                        ++i;
                    }
                }
                if (noiseScale > 0.0f) {
                    for (size_t i = 0; i < nx; ++i)
                        row[i] += noiseScale * float(noiseSample(int(i), int(j), int(k), seed));
                }
            }
            ++slicesDone;
        }
    });
    if (cancelled) throw Cancelled();
    pollInterrupter(interrupter, 100);
    return scan;
}

Volume makePhantom(const PhantomOptions& options, Interrupter* interrupter)
{
    return makeVolume(makePhantomScan(options, interrupter), "phantom", {}, interrupter);
}

} // namespace mtcut::vdb
