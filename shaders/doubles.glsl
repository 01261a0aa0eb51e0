#extension GL_ARB_gpu_shader_int64 : require
// Double arithmetic rounded as the C++ rounds it, on any driver: the first
// library in front of the GPU cut pass's programs (render/CutKernelGpu.cpp,
// cutPassLibrary), poly2_test.comp and doubles_test.comp (hence the
// #extension here, which must come before any code). GLSL asks no correct
// rounding of division and square root. On NVIDIA 580.159.04 (H100) the
// driver's double sqrt was an ulp off for 1,122 of 4,096 inputs, its division
// exact for all (RenderPoly2.DoublesReachTheShaderUnrounded, which checks
// both on every driver); on llvmpipe both are exact. So the shaders take
// every double square root through dSqrt, which is std::sqrt's value there too.

// Veltkamp's split of x into hi + lo, 26 bits each (precise: no fma, which
// would make the split inexact).
void dSplit(double x, out double hi, out double lo)
{
    precise double t = 134217729.0lf * x;
    precise double h = t - (t - x);
    hi = h;
    precise double l = x - h;
    lo = l;
}

// a - c b, exact up to its one rounding at the end (Dekker's product), for c
// near a / b: how far c is from the quotient (or, with b = c, the root).
double dResidual(double a, double c, double b)
{
    double ch, cl, bh, bl;
    dSplit(c, ch, cl);
    dSplit(b, bh, bl);
    precise double p = c * b;
    precise double e = ((ch * bh - p) + ch * bl + cl * bh) + cl * bl; // c b = p + e exactly
    precise double r = (a - p) - e;
    return r;
}

// The next double above (up) or below a finite x != 0.
double dNext(double x, bool up)
{
    uvec2 u = unpackDouble2x32(x); // (low word, high word)
    if ((x > 0.0lf) == up) {
        u.x += 1u;
        if (u.x == 0u) u.y += 1u;
    } else {
        if (u.x == 0u) u.y -= 1u;
        u.x -= 1u;
    }
    return packDouble2x32(u);
}

// The double c nearest a / b (root: sqrt(a)) from an x at most 3 ulps away:
// the residual a - c b (a - c c) grows both ways from c, so from x it steps
// to the neighbour with the smaller |residual| while there is one, at most 3
// steps. Written without loops: llvmpipe's loop limiter counts every
// iteration of an invocation, and the callers' loops are long (a loop here
// cut poly2's largest cases short there).
double dWalk(double a, double b, double x, bool root)
{
    if (x == 0.0lf || isinf(x) || isnan(x)) return x;
    const double r0 = abs(dResidual(a, x, root ? x : b));
    const double up = dNext(x, true), down = dNext(x, false);
    const double ru = abs(dResidual(a, up, root ? up : b)), rd = abs(dResidual(a, down, root ? down : b));
    const bool goUp = ru < r0;
    if (!goUp && !(rd < r0)) return x;
    const double c1 = goUp ? up : down, r1 = goUp ? ru : rd;
    const double c2 = dNext(c1, goUp), r2 = abs(dResidual(a, c2, root ? c2 : b));
    if (!(r2 < r1)) return c1;
    const double c3 = dNext(c2, goUp), r3 = abs(dResidual(a, c3, root ? c3 : b));
    return r3 < r2 ? c3 : c2;
}

// a / b rounded to nearest from q (a quotient of doubles is never half way
// between two).
double dDivFrom(double a, double b, double q) { return dWalk(a, b, q, false); }

// sqrt(a) rounded to nearest from s (a root is never half way either;
// |a - c c| and |sqrt(a) - c| differ by the factor sqrt(a) + c, an ulp or two
// apart between neighbours, which could decide only a root within that of
// half way).
double dSqrtFrom(double a, double s) { return dWalk(a, 0.0lf, s, true); }

// std::sqrt(a) for a >= 0.
double dSqrt(double a)
{
    return dSqrtFrom(a, sqrt(a));
}
