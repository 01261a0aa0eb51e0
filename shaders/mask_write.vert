#version 450 core
// Mask coding (render/MaskAtlas.h): one point per cut cell, placed on its
// tile's atlas texel; the fragment shader sets the cell's bit (OR logic-op).
layout(location = 0) in ivec3 aCell;

flat out int vWord; // 0..15, or -1: the cell has no tile (the point is clipped)
flat out uint vBit;

void main()
{
    uint slot = maskSlotOf(aCell);
    gl_PointSize = 1.0;
    if (slot == 0u) {
        vWord = -1;
        vBit = 0u;
        gl_Position = vec4(2.0, 2.0, 2.0, 1.0); // outside the clip volume
        return;
    }
    int s = int(slot - 1u);
    vec2 texel = vec2(s % uMaskAtlasWidth, s / uMaskAtlasWidth) + 0.5;
    gl_Position = vec4(texel / vec2(uMaskAtlasWidth, uMaskAtlasHeight) * 2.0 - 1.0, 0.0, 1.0);
    int n = maskBitOf(aCell);
    vWord = n >> 5;
    vBit = uint(n & 31);
}
