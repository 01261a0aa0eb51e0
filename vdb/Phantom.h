// A procedural CT-head phantom in HU: the built-in default input and the large
// benchmark volume.
//
// The head is built from analytic shapes (ellipsoids, capsules, rounded boxes,
// tori and swept arches) with signed distances in millimetres, painted in
// order (later tissue replaces earlier tissue). Each boundary is a smooth step
// one voxel wide (partial-volume blur), so any grid size samples the same head.
// Anatomy (world frame LPS, mm; +x patient's left, +y posterior, +z superior;
// the head is centred on x = 0):
//   - scalp (skin, subcutaneous fat, muscle) over a cranial vault with outer
//     table, diploe and inner table, CSF, brain and lateral ventricles; a
//     sloped skull base with a foramen magnum;
//   - face at -y: orbits (bony wall, fat, globe), frontal sinus in a brow
//     ridge, nasal bones, nasal cavity with septum, zygomatic arches, the
//     maxilla with two maxillary sinuses and the upper alveolar ridge;
//   - 14 upper and 14 lower teeth (dentin roots in bone, enamel crowns), the
//     upper crowns 4.5 mm above the lower ones (the jaw slightly open);
//   - the mandible (body along the lower arch, rami, condyles) clear of the
//     skull, and 7 cervical vertebrae (body, arch, spinous and transverse
//     processes) with discs, spinal cord and the airway in front.
// Bone >= 400 HU forms 9 separate pieces: skull with maxilla and upper teeth,
// mandible with lower teeth, and each vertebra.
#pragma once

#include "vdb/Volume.h"

#include <cstdint>
#include <vector>

namespace mtcut::vdb {

struct PhantomOptions
{
    openvdb::Coord dims{512, 512, 256}; ///< grid size; the head's size in mm is fixed
    uint32_t seed = 1;                  ///< noise seed; same seed, same volume
    /// Standard deviation of the noise, HU. The noise is a sum of four uniform
    /// variates (Irwin-Hall), so it is bounded: |noise| <= 2*sqrt(3)*noiseSigma.
    /// 0 gives the noise-free phantom. Must be >= 0.
    float noiseSigma = 15.0f;
};

/// Physical extent of the phantom's grid in mm along x, y, z (240 x 240 x 256);
/// spacing = phantomFieldOfView() / dims, so voxel centres lie at
/// origin + spacing * ijk with origin = -fov/2 + spacing/2 (the field of view is
/// centred on the world origin).
openvdb::Vec3d phantomFieldOfView();

/// World points (mm, LPS) inside known anatomy, the same at every grid size
/// (computed from the same shapes the phantom paints). The HU stated are those
/// of the noise-free phantom on a fine grid, away from partial volume.
struct PhantomLandmarks
{
    openvdb::Vec3d outsideHead;       ///< air, -1000
    openvdb::Vec3d brain;             ///< brain, 32
    openvdb::Vec3d skullLateral;      ///< middle of the outer table on the left side, 1600
    openvdb::Vec3d vertexBone;        ///< middle of the outer table at the top, 1600
    double skullTopZ = 0.0;           ///< z of the highest bone (outer table at the vertex)
    openvdb::Vec3d maxillarySinus;    ///< centre of the left maxillary sinus, -1000
    openvdb::Vec3d maxillaBone;       ///< cancellous maxilla under the nasal cavity, 480
    openvdb::Vec3d upperIncisorCrown; ///< centre of the upper left central incisor's enamel, 2700
    openvdb::Vec3d upperMolarCrown;   ///< centre of the last upper left molar's enamel, 2700
    openvdb::Vec3d lowerIncisorCrown; ///< centre of the lower left central incisor's enamel, 2700
    openvdb::Vec3d mandibleBone;      ///< cancellous left mandible body behind the teeth, 480
    std::vector<openvdb::Vec3d> vertebraBodies; ///< centres of the 7 vertebral bodies, top first, 480
    openvdb::Vec3d vertebraBody;      ///< vertebraBodies[2], the third vertebra
    double upperCrownBottomZ = 0.0;   ///< lowest z of the upper crowns
    double lowerCrownTopZ = 0.0;      ///< highest z of the lower crowns (a gap below the upper ones)
    /// A LeFort I osteotomy plane z = leFortZ: through the maxilla, the
    /// maxillary sinuses and the nasal cavity, above the upper roots' tips.
    double leFortZ = 0.0;
};

/// The landmarks of the phantom (constant).
PhantomLandmarks phantomLandmarks();

/// The phantom as a dense scan (HU), geometry as phantomFieldOfView() says,
/// identity direction. Deterministic from (dims, seed, noiseSigma), whatever
/// the thread count: every voxel is a pure function of its index and the seed
/// (noise from a hash of (i, j, k, seed)). Throws InputError on bad dims
/// (checkDims) or a negative or non-finite noiseSigma. Parallel over z slabs (TBB); polls
/// interrupter once per slab with the percentage done (throws Cancelled).
/// Cost: 1.4 s for 512 x 512 x 256 on a shared 2-core VM (benchmarks/RESULTS.md);
/// memory: the dense array (4 bytes a voxel).
DenseScan makePhantomScan(const PhantomOptions& options, Interrupter* interrupter = nullptr);

/// makePhantomScan, made sparse (makeVolume, air threshold -500 HU); source
/// "phantom". Peak memory: the dense array plus the sparse grid (374 MiB for
/// 512 x 512 x 256, whose grid is 0.4 x the dense array).
Volume makePhantom(const PhantomOptions& options, Interrupter* interrupter = nullptr);

} // namespace mtcut::vdb
