// Mask lookup (render/MaskAtlas.h): put in front of a shader body by
// buildProgram's defines. maskIsCut(cell) is true when cell (i,j,k) is set.
// Tiles are OpenVDB leaves: bit n = 64 (i & 7) + 8 (j & 7) + (k & 7) of the
// tile's 16 words; word w is component w & 3 of layer w >> 2 of the atlas.
uniform ivec3 uMaskLeafMin;      // leaf coordinates of the leaf box's low corner
uniform ivec3 uMaskLeafExtent;   // leaves per axis (0 when the mask is empty)
uniform int uMaskIndirectionWidth;
uniform int uMaskAtlasWidth;
uniform int uMaskAtlasHeight;
layout(binding = 0) uniform usampler2D uMaskIndirection;
layout(binding = 1) uniform usampler2DArray uMaskAtlas;

// Slot + 1 of the tile holding cell, or 0 when no tile holds it.
uint maskSlotOf(ivec3 cell)
{
    ivec3 l = (cell >> 3) - uMaskLeafMin; // >> sign-extends: floor division by 8
    if (any(lessThan(l, ivec3(0))) || any(greaterThanEqual(l, uMaskLeafExtent))) return 0u;
    int i = l.x + uMaskLeafExtent.x * (l.y + uMaskLeafExtent.y * l.z);
    return texelFetch(uMaskIndirection, ivec2(i % uMaskIndirectionWidth, i / uMaskIndirectionWidth), 0).r;
}

// The bit index of cell inside its tile.
int maskBitOf(ivec3 cell)
{
    ivec3 l = cell & 7;
    return (l.x << 6) | (l.y << 3) | l.z;
}

bool maskIsCut(ivec3 cell)
{
    uint slot = maskSlotOf(cell);
    if (slot == 0u) return false;
    int s = int(slot - 1u);
    int n = maskBitOf(cell);
    int w = n >> 5;
    uvec4 t = texelFetch(uMaskAtlas, ivec3(s % uMaskAtlasWidth, s / uMaskAtlasWidth, w >> 2), 0);
    return ((t[w & 3] >> uint(n & 31)) & 1u) != 0u;
}
