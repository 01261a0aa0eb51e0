#version 450 core
// Flat-coloured overlay geometry (the viewer's blade): world mm in.
layout(location = 0) in vec3 aPosition; // world mm

uniform mat4 uViewProjection;

void main()
{
    gl_Position = uViewProjection * vec4(aPosition, 1.0);
}
