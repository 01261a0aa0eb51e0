#version 450 core
// The viewer's blade over a SurfaceRenderer frame (render/BladeOverlay.h): its
// colour where it lies in front of the frame's surface, faded to
// uHiddenAlpha x the alpha where the surface hides it, so the part of the
// blade inside the bone stays visible but reads as behind it.
uniform vec4 uColour;
uniform float uHiddenAlpha;
layout(binding = 0) uniform sampler2D uSceneDepth; // the frame's depth buffer, same size as the target

layout(location = 0) out vec4 oColour;

void main()
{
    const float scene = texelFetch(uSceneDepth, ivec2(gl_FragCoord.xy), 0).r;
    const bool hidden = gl_FragCoord.z > scene;
    oColour = vec4(uColour.rgb, uColour.a * (hidden ? uHiddenAlpha : 1.0));
}
