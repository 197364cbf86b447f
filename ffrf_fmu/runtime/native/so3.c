/* Rotation helpers of the runtime (the C twins of runtime/rotation.py): 3x3 matrices row-major. */
#include <math.h>

#include "so3.h"

#define EPS_TANGENT 1e-5 /* rotation.py: below this angle the series of the tangent are exact to round-off */

/* exp(skew(th)) through the unit quaternion (cos(t/2), sin(t/2)/t th), as rotation.expm. */
void ffrf_expm(const double th[3], double out[9])
{
    double t2 = th[0] * th[0] + th[1] * th[1] + th[2] * th[2];
    double half = sqrt(0.25 * t2);
    double w = cos(half);
    double s = half > 0.0 ? sin(half) / half : 0.0;
    double x = 0.5 * s * th[0], y = 0.5 * s * th[1], z = 0.5 * s * th[2];
    double d = w * w - x * x - y * y - z * z;
    out[0] = d + 2 * x * x;
    out[4] = d + 2 * y * y;
    out[8] = d + 2 * z * z;
    out[1] = 2 * (x * y - w * z);
    out[3] = 2 * (x * y + w * z);
    out[2] = 2 * (x * z + w * y);
    out[6] = 2 * (x * z - w * y);
    out[5] = 2 * (y * z - w * x);
    out[7] = 2 * (y * z + w * x);
}

void ffrf_skew(const double a[3], double out[9])
{
    out[0] = 0.0;   out[1] = -a[2]; out[2] = a[1];
    out[3] = a[2];  out[4] = 0.0;   out[5] = -a[0];
    out[6] = -a[1]; out[7] = a[0];  out[8] = 0.0;
}

void ffrf_cross(const double a[3], const double b[3], double out[3])
{
    out[0] = a[1] * b[2] - a[2] * b[1];
    out[1] = a[2] * b[0] - a[0] * b[2];
    out[2] = a[0] * b[1] - a[1] * b[0];
}

/* T(th) = I - b skew(th) + c skew(th)^2 (rotation.tangent). */
void ffrf_tangent(const double th[3], double out[9])
{
    double t2 = th[0] * th[0] + th[1] * th[1] + th[2] * th[2];
    double t = sqrt(t2), b, c, S[9];
    if (t < EPS_TANGENT) {
        b = 0.5 - t2 / 24.0;
        c = 1.0 / 6.0 - t2 / 120.0;
    } else {
        b = (1.0 - cos(t)) / t2;
        c = (t - sin(t)) / (t2 * t);
    }
    ffrf_skew(th, S);
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++) {
            double ss = 0.0;
            for (int k = 0; k < 3; k++)
                ss += S[3 * i + k] * S[3 * k + j];
            out[3 * i + j] = (i == j ? 1.0 : 0.0) - b * S[3 * i + j] + c * ss;
        }
}

/* Rotation vector of M (rotation.logm: the angle atan2(sin t, cos t) of the skew part and the trace,
 * accurate at every angle; near pi the axis from the symmetric part). */
void ffrf_logm(const double M[9], double out[3])
{
    double v0 = 0.5 * (M[7] - M[5]), v1 = 0.5 * (M[2] - M[6]), v2 = 0.5 * (M[3] - M[1]);
    double cs = 0.5 * (M[0] + M[4] + M[8]) - 0.5;
    double sn = sqrt(v0 * v0 + v1 * v1 + v2 * v2);
    double t = atan2(sn, cs), t2 = t * t;
    double factor = t < 1e-2 ? 1.0 + t2 / 6.0 + 7.0 * t2 * t2 / 360.0 : t / sn;
    out[0] = factor * v0;
    out[1] = factor * v1;
    out[2] = factor * v2;
    if (t > FFRF_PI - 1e-4) {
        int k = 0;
        for (int i = 0; i < 3; i++)
            if (M[4 * i] - cs > M[4 * k] - cs)
                k = i;
        double col[3];
        for (int i = 0; i < 3; i++)
            col[i] = 0.5 * (M[3 * i + k] + M[3 * k + i]) - (i == k ? cs : 0.0);
        double nrm = sqrt(col[0] * col[0] + col[1] * col[1] + col[2] * col[2]);
        double sign = col[0] * v0 + col[1] * v1 + col[2] * v2 < 0.0 ? -1.0 : 1.0;
        for (int i = 0; i < 3; i++)
            out[i] = t * sign * col[i] / nrm;
    }
}

/* Inverse of a 3 x 3 matrix by cofactors. */
void ffrf_inv3(const double A[9], double out[9])
{
#define a(i, j) A[3 * (i) + (j)]
    double c00 = a(1, 1) * a(2, 2) - a(1, 2) * a(2, 1);
    double c01 = a(1, 2) * a(2, 0) - a(1, 0) * a(2, 2);
    double c02 = a(1, 0) * a(2, 1) - a(1, 1) * a(2, 0);
    double d = a(0, 0) * c00 + a(0, 1) * c01 + a(0, 2) * c02;
    out[0] = c00 / d;
    out[3] = c01 / d;
    out[6] = c02 / d;
    out[1] = (a(0, 2) * a(2, 1) - a(0, 1) * a(2, 2)) / d;
    out[4] = (a(0, 0) * a(2, 2) - a(0, 2) * a(2, 0)) / d;
    out[7] = (a(0, 1) * a(2, 0) - a(0, 0) * a(2, 1)) / d;
    out[2] = (a(0, 1) * a(1, 2) - a(0, 2) * a(1, 1)) / d;
    out[5] = (a(0, 2) * a(1, 0) - a(0, 0) * a(1, 2)) / d;
    out[8] = (a(0, 0) * a(1, 1) - a(0, 1) * a(1, 0)) / d;
#undef a
}
