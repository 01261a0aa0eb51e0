#version 450 core
// For the test of loopLimitHit() (cut_kernel.glsl, prepended): vertex 0
// runs a loop of uTrips iterations, then asks the probe.
layout(std430, binding = 10) writeonly buffer ProbeOut { int probeOut[]; };
uniform int uTrips;

void main()
{
    if (gl_VertexID != 0) return;
    int n = 0;
    for (int i = 0; i < uTrips; ++i) ++n;
    probeOut[0] = n;
    probeOut[1] = loopLimitHit() ? 1 : 0;
}
