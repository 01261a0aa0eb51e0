#version 450 core
// Mask coding: each of the 4 integer attachments is one atlas layer (tile
// words 4L..4L+3); only the cell's word gets its bit, the rest stay 0, and
// glLogicOp(GL_OR) merges it with the bits already there.
flat in int vWord;
flat in uint vBit;

layout(location = 0) out uvec4 oLayer0;
layout(location = 1) out uvec4 oLayer1;
layout(location = 2) out uvec4 oLayer2;
layout(location = 3) out uvec4 oLayer3;

void main()
{
    if (vWord < 0) discard;
    uvec4 v = uvec4(0u);
    v[vWord & 3] = 1u << vBit;
    int layer = vWord >> 2;
    oLayer0 = layer == 0 ? v : uvec4(0u);
    oLayer1 = layer == 1 ? v : uvec4(0u);
    oLayer2 = layer == 2 ? v : uvec4(0u);
    oLayer3 = layer == 3 ? v : uvec4(0u);
}
