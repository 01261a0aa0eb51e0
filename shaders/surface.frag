#version 450 core
// Phong shading with a headlight, into four targets: colour, world normal,
// view depth (mm) and fragment id. With DISCARD_CUT defined (the discard
// pass, DESIGN "GPU passes") a triangle whose cell is set in the cut mask is
// discarded; the triangle's cell comes from its gl_PrimitiveID, never from
// the fragment's position, so the test is exact.
in vec3 vWorldPos;
in vec3 vNormal;
in float vViewDepth;

// Per triangle of the draw: cell (i,j,k) and info = fragment id (bits 0..29)
// | cap (bit 30) | cut geometry (bit 31).
struct TriangleInfo
{
    ivec3 cell;
    uint info;
};
layout(std430, binding = 2) readonly buffer Triangles { TriangleInfo uTriangles[]; };

uniform vec3 uEye;             // world mm
uniform vec3 uColour;          // surface colour
uniform vec3 uHighlightColour; // cut geometry when uHighlight: caps in it, the
                               // cut cells' isosurface pieces half-way to it
uniform bool uHighlight;
// Optional colours per fragment id (rgb; a = 0 hides the fragment's
// triangles); ids >= uFragmentColourCount keep uColour. 0: none.
layout(std430, binding = 3) readonly buffer FragmentColours { vec4 uFragmentColours[]; };
uniform uint uFragmentColourCount;

layout(location = 0) out vec4 oColour;
layout(location = 1) out vec4 oNormal;
layout(location = 2) out float oDepth;
layout(location = 3) out uint oFragment;

void main()
{
    TriangleInfo t = uTriangles[gl_PrimitiveID];
#ifdef DISCARD_CUT
    if (maskIsCut(t.cell)) discard;
#endif
    vec3 n = normalize(vNormal);
    if (!gl_FrontFacing) n = -n;
    vec3 toEye = normalize(uEye - vWorldPos);
    float diffuse = max(dot(n, toEye), 0.0);
    float specular = pow(max(dot(reflect(-toEye, n), toEye), 0.0), 40.0);
    vec3 base = uColour;
    uint fragment = t.info & 0x3fffffffu;
    if (fragment < uFragmentColourCount) {
        vec4 styled = uFragmentColours[fragment];
        if (styled.a == 0.0) discard;
        base = styled.rgb;
    }
    if (uHighlight && (t.info & 0x80000000u) != 0u) {
        base = (t.info & 0x40000000u) != 0u ? uHighlightColour : mix(uColour, uHighlightColour, 0.55);
    }
    oColour = vec4(base * (0.18 + 0.74 * diffuse) + vec3(0.22 * specular), 1.0);
    oNormal = vec4(n, 0.0);
    oDepth = vViewDepth;
    oFragment = fragment;
}
