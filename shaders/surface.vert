#version 450 core
// Surfaces (uncut isosurface, cut geometry, fused meshes): world mm in,
// Phong shading in surface.frag.
layout(location = 0) in vec3 aPosition; // world mm
layout(location = 1) in vec3 aNormal;   // unit, outward

uniform mat4 uViewProjection;
uniform mat4 uView;

out vec3 vWorldPos;
out vec3 vNormal;
out float vViewDepth; // mm along the view direction

void main()
{
    vWorldPos = aPosition;
    vNormal = aNormal;
    vViewDepth = -(uView * vec4(aPosition, 1.0)).z;
    gl_Position = uViewProjection * vec4(aPosition, 1.0);
}
