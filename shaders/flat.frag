#version 450 core
// One colour with alpha (blended by the caller).
uniform vec4 uColour;

layout(location = 0) out vec4 oColour;

void main()
{
    oColour = uColour;
}
