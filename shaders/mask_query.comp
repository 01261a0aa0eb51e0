#version 450 core
// Answers maskIsCut for a list of cells (tests and tools): cell i is read
// from uCells[i] (xyz), the answer (0 or 1) written to uAnswers[i].
layout(local_size_x = 64) in;
layout(std430, binding = 0) readonly buffer Cells { ivec4 uCells[]; };
layout(std430, binding = 1) writeonly buffer Answers { uint uAnswers[]; };
uniform uint uCount;

void main()
{
    uint i = gl_GlobalInvocationID.x;
    if (i >= uCount) return;
    uAnswers[i] = maskIsCut(uCells[i].xyz) ? 1u : 0u;
}
