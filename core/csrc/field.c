/* The planner's lookups on a distance field: see field.h. */
#include <math.h>

#include "field.h"

/* Bilinear signed distance at one point (DistanceField.at's formula, operation for operation). */
static double field_at(const double *values, long ny, long nx, double x0, double y0, double h,
                       double x, double y) {
    const double u = (x - x0) / h, v = (y - y0) / h;
    double j, i, a, b;
    const double *f;
    if (!(u >= 0.0 && u <= (double)(nx - 1) && v >= 0.0 && v <= (double)(ny - 1))) {
        return -HUGE_VAL;
    }
    j = floor(u);
    i = floor(v);
    if (j > (double)(nx - 2)) {
        j = (double)(nx - 2);
    }
    if (i > (double)(ny - 2)) {
        i = (double)(ny - 2);
    }
    a = u - j;
    b = v - i;
    f = values + (long)i * nx + (long)j;
    return (1.0 - b) * ((1.0 - a) * f[0] + a * f[1]) + b * ((1.0 - a) * f[nx] + a * f[nx + 1]);
}

void pt_field_at(const double *values, long ny, long nx, double x0, double y0, double h,
                 long count, const double *x, const double *y, double *out) {
    long q;
    for (q = 0; q < count; q++) {
        out[q] = field_at(values, ny, nx, x0, y0, h, x[q], y[q]);
    }
}

/* Steps of one segment of `length` [m] at `spacing` [m]: max(1, ceil(length / spacing)). */
static long steps_of(double length, double spacing) {
    const double m = ceil(length / spacing);
    return m > 1.0 ? (long)m : 1;
}

long pt_sample_count(int n_segments, const double *segments, double spacing) {
    long total = 1;
    int g;
    if (n_segments < 0 || (n_segments > 0 && segments == NULL) || !(spacing > 0.0) ||
        !isfinite(spacing)) {
        return -1;
    }
    for (g = 0; g < n_segments; g++) {
        const double length = segments[3 * g];
        if (!isfinite(length) || length < 0.0 || length / spacing > 1e15) {
            return -1;
        }
        total += steps_of(length, spacing);
    }
    return total;
}

int pt_sample_segments(const double pose[3], int n_segments, const double *segments,
                       double spacing, double *out) {
    double x, y, th;
    long row = 1;
    int g;
    if (pose == NULL || out == NULL || pt_sample_count(n_segments, segments, spacing) < 1) {
        return PT_ERR_ARGUMENT;
    }
    x = pose[0];
    y = pose[1];
    th = pose[2];
    out[0] = x;
    out[1] = y;
    out[2] = th;
    for (g = 0; g < n_segments; g++) {
        const double length = segments[3 * g], k = segments[3 * g + 1];
        const double sigma = -segments[3 * g + 2];
        const long m = steps_of(length, spacing);
        const double ds = length / (double)m;
        long q;
        if (fabs(k) < 1e-12) {
            const double dx = sigma * ds * cos(th), dy = sigma * ds * sin(th);
            for (q = 0; q < m; q++, row++) {
                x += dx;
                y += dy;
                out[3 * row] = x;
                out[3 * row + 1] = y;
                out[3 * row + 2] = th;
            }
        } else {
            const double dth = k * ds;
            double s0 = sin(th), c0 = cos(th);
            for (q = 0; q < m; q++, row++) {
                double s1, c1;
                th += dth;
                s1 = sin(th);
                c1 = cos(th);
                x += sigma * (s1 - s0) / k;
                y += -(sigma * (c1 - c0) / k);
                s0 = s1;
                c0 = c1;
                out[3 * row] = x;
                out[3 * row + 1] = y;
                out[3 * row + 2] = th;
            }
        }
    }
    return PT_OK;
}

int pt_poses_clear(const double *values, long ny, long nx, double x0, double y0, double h,
                   long count, const double *poses, double reach, long m, const double *u,
                   const double *v, const double *threshold) {
    long q, p;
    for (q = 0; q < count; q++) {
        const double x = poses[3 * q], y = poses[3 * q + 1], th = poses[3 * q + 2];
        double c, s;
        if (!(field_at(values, ny, nx, x0, y0, h, x, y) < reach)) {
            continue; /* clear by its whole reach (or a NaN node: not "close") */
        }
        c = cos(th);
        s = sin(th);
        for (p = 0; p < m; p++) {
            const double px = x + u[p] * c - v[p] * s;
            const double py = y + u[p] * s + v[p] * c;
            if (!(field_at(values, ny, nx, x0, y0, h, px, py) >= threshold[p])) {
                return 0;
            }
        }
    }
    return 1;
}
