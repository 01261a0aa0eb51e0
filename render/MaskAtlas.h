// The GPU coding of a sparse cell mask (DESIGN "GPU passes", mask coding; the
// MTCut paper's step 1 without its 16-bit blending depth limit). Tiles (8^3
// cells = 512 bits) live in an integer atlas, a GL_RGBA32UI 2D array texture
// of 4 layers: slot s is texel (s % width, s / width), layer L holds tile
// words 4L..4L+3. An R32UI 2D texture holds the indirection (slot + 1 per leaf
// of the leaf box, linearised x fastest, then y, then z, wrapped at its
// width), so any number of slices works (a 3D texture would stop at 2048
// leaves on llvmpipe).
//
// Two ways to fill the atlas: writeCells() renders one GL_POINT per cell into
// the 4 layers bound as integer colour attachments with glLogicOp(GL_OR),
// each point setting its bit; uploadTiles() uploads the leaf masks from the
// CPU (the fallback). Both give the same words (tested).
#pragma once

#include "render/GlObjects.h"
#include "render/MaskTiling.h"

#include <cstdint>
#include <string>
#include <vector>

namespace mtcut::render {

class MaskAtlas
{
public:
    /// Allocates the atlas for `tiling`'s slots and uploads its indirection
    /// (not its bits: call writeCells or uploadTiles). Needs a current
    /// context. Throws std::runtime_error when the slots exceed the largest
    /// 2D texture (width * height texels).
    explicit MaskAtlas(const MaskTiling& tiling);

    /// CPU fallback: uploads tiling.words (the same tiling as the constructor's).
    void uploadTiles(const MaskTiling& tiling);
    /// GPU coding: clears the atlas, then sets the bit of every cell with one
    /// point each (OR logic-op into the 4 integer attachments). Cells in no
    /// slot of the tiling are ignored. Cost: one draw of cells.size() points.
    void writeCells(const std::vector<openvdb::Coord>& cells);
    /// Reads the atlas back: kTileWords per slot, as MaskTiling::words.
    std::vector<uint32_t> readWords() const;
    /// maskIsCut(cell) evaluated on the GPU for each cell (compute shader
    /// shaders/mask_query.comp through the sampling path): 1 when set.
    std::vector<uint8_t> queryCells(const std::vector<openvdb::Coord>& cells) const;

    size_t slotCount() const { return mSlots; }
    int atlasWidth() const { return mWidth; }
    int atlasHeight() const { return mHeight; }

    /// Binds the indirection to texture unit 0 and the atlas to unit 1 and sets
    /// the uniforms that shaders/mask.glsl declares in `program` (which must be
    /// in use). After this, maskIsCut(cell) in that program answers for this mask.
    void bindForSampling(const Program& program) const;

private:
    void setLookupUniforms(const Program& program) const;

    size_t mSlots = 0;
    int mWidth = 1, mHeight = 1;
    int mIndirectionWidth = 1, mIndirectionHeight = 1;
    openvdb::Coord mLeafMin{0, 0, 0}, mLeafExtent{0, 0, 0};
    Texture mAtlas{GL_TEXTURE_2D_ARRAY};
    Texture mIndirection{GL_TEXTURE_2D};
};

/// The GLSL helpers (shaders/mask.glsl) to put in front of a shader body that
/// calls maskIsCut(ivec3 cell): pass as `defines` to buildProgram.
std::string maskShaderLibrary();

} // namespace mtcut::render
