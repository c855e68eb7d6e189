/*
 * The fast closed-loop integrator (see rollout.h): the loop core.engine.simulate runs (its
 * readable twin tests/reference/closed_loop.py, the same order of floating-point operations),
 * plus the body checks.
 */
#include <math.h>
#include <stddef.h>
#include <string.h>

#include "rollout.h"
#include "ode.h"

/* Work layout for n trailers (nz = 3 + n state components). */
#define RK_STAGES 5 /* k1, k2, k3, k4, tmp */

size_t pt_rollout_sizeof(int which) {
    switch (which) {
    case 0: return sizeof(PtChecks);
    case 1: return sizeof(PtRollout);
    case 2: return sizeof(PtViolation);
    case 3: return sizeof(PtRecord);
    default: return 0;
    }
}

int pt_rollout_work(int n) {
    const int nz = 3 + n;
    return RK_STAGES * nz + n + 9 * (n + 1);
}

/* The train under a held command (v0 [m/s], w0 [rad/s]). */
typedef struct {
    const PtChain *plant;
    double v0, w0;
} Held;

/* dz/dt of the robot moving along its heading with the held command and the towed chain (the
 * f of train_check._rk4_step). */
static inline void plant_rates(const void *context, double t, const double *z, double *dz) {
    const Held *held = (const Held *)context;
    (void)t;
    dz[0] = held->v0 * cos(z[2]);
    dz[1] = held->v0 * sin(z[2]);
    pt_towed_rates(held->plant, z + 2, held->v0, held->w0, dz + 2);
}

/* One RK4 step of h under the held command (ode.rk4_step). */
static void plant_rk4(const PtChain *plant, double *z, double v0, double w0, double h,
                      double *work) {
    Held held;
    held.plant = plant;
    held.v0 = v0;
    held.w0 = w0;
    pt_rk4_step(plant_rates, &held, 0.0, z, 3 + plant->n, h, work);
}

int pt_hold(const PtChain *plant, double *z, double v0, double w0, double h, int count,
            double *states, double *work) {
    const int nz = plant == NULL ? 0 : 3 + plant->n;
    int j;
    if (plant == NULL || plant->n < 1 || z == NULL || work == NULL || count < 0 ||
        (count > 0 && states == NULL)) {
        return PT_ERR_ARGUMENT;
    }
    for (j = 0; j < count; j++) {
        plant_rk4(plant, z, v0, w0, h, work);
        memcpy(states + (size_t)j * (size_t)nz, z, sizeof(double) * (size_t)nz);
    }
    return PT_OK;
}

/* ------------------------------------------------------------------ checks */

double pt_sdf_at(const PtChecks *c, double x, double y) {
    const double tol = 1e-9; /* of a cell: the grid's edges computed with rounding count */
    const double x_last = (double)(c->nx - 1), y_last = (double)(c->ny - 1);
    double fx = (x - c->x0) / c->h, fy = (y - c->y0) / c->h;
    double tx, ty;
    int i, j;
    const double *row0, *row1;
    if (!(fx >= -tol && fx <= x_last + tol && fy >= -tol && fy <= y_last + tol)) {
        return -HUGE_VAL;
    }
    fx = fx < 0.0 ? 0.0 : (fx > x_last ? x_last : fx);
    fy = fy < 0.0 ? 0.0 : (fy > y_last ? y_last : fy);
    j = (int)fx;
    i = (int)fy;
    if (j > c->nx - 2) {
        j = c->nx - 2;
    }
    if (i > c->ny - 2) {
        i = c->ny - 2;
    }
    tx = fx - (double)j;
    ty = fy - (double)i;
    row0 = c->sdf + (size_t)i * (size_t)c->nx + (size_t)j;
    row1 = row0 + c->nx;
    return (1.0 - ty) * ((1.0 - tx) * row0[0] + tx * row0[1]) +
           ty * ((1.0 - tx) * row1[0] + tx * row1[1]);
}

/* Whether point (x, y) lies strictly inside rectangle r = (cx, cy, theta, hl, hw). */
static int inside_rect(const double r[5], double x, double y) {
    const double c = cos(r[2]), s = sin(r[2]);
    const double dx = x - r[0], dy = y - r[1];
    return fabs(c * dx + s * dy) < r[3] && fabs(-s * dx + c * dy) < r[4];
}

/* Corner q (0..3) of rectangle r. */
static void rect_corner(const double r[5], int q, double out[2]) {
    const double c = cos(r[2]), s = sin(r[2]);
    const double a = (q == 0 || q == 3) ? r[3] : -r[3];
    const double b = (q < 2) ? r[4] : -r[4];
    out[0] = r[0] + a * c - b * s;
    out[1] = r[1] + a * s + b * c;
}

/* A point where an edge of rectangle a crosses an edge of rectangle b, if one does. */
static int edges_cross(const double a[5], const double b[5], double pt[2]) {
    int qa, qb;
    for (qa = 0; qa < 4; qa++) {
        double p0[2], p1[2];
        rect_corner(a, qa, p0);
        rect_corner(a, (qa + 1) % 4, p1);
        for (qb = 0; qb < 4; qb++) {
            double q0[2], q1[2], rx, ry, sx, sy, den, u, v;
            rect_corner(b, qb, q0);
            rect_corner(b, (qb + 1) % 4, q1);
            rx = p1[0] - p0[0];
            ry = p1[1] - p0[1];
            sx = q1[0] - q0[0];
            sy = q1[1] - q0[1];
            den = rx * sy - ry * sx;
            if (den == 0.0) {
                continue;
            }
            u = ((q0[0] - p0[0]) * sy - (q0[1] - p0[1]) * sx) / den;
            v = ((q0[0] - p0[0]) * ry - (q0[1] - p0[1]) * rx) / den;
            if (u >= 0.0 && u <= 1.0 && v >= 0.0 && v <= 1.0) {
                pt[0] = p0[0] + u * rx;
                pt[1] = p0[1] + u * ry;
                return 1;
            }
        }
    }
    return 0;
}

/* pt_rects_overlap with the rectangles' cos and sin of their headings given: (ca, sa), (cb, sb).
 * A first test of their circumscribed circles rejects far pairs without the axes. */
static int rects_overlap_cs(const double a[5], const double b[5], double ca, double sa, double cb,
                            double sb, double pt[2]) {
    const double axes[4][2] = {{ca, sa}, {-sa, ca}, {cb, sb}, {-sb, cb}};
    const double dx = b[0] - a[0], dy = b[1] - a[1];
    const double reach = sqrt(a[3] * a[3] + a[4] * a[4]) + sqrt(b[3] * b[3] + b[4] * b[4]);
    int q;
    if (dx * dx + dy * dy >= reach * reach) {
        return 0;
    }
    for (q = 0; q < 4; q++) {
        const double lx = axes[q][0], ly = axes[q][1];
        const double ra = a[3] * fabs(ca * lx + sa * ly) + a[4] * fabs(-sa * lx + ca * ly);
        const double rb = b[3] * fabs(cb * lx + sb * ly) + b[4] * fabs(-sb * lx + cb * ly);
        if (fabs(dx * lx + dy * ly) >= ra + rb) {
            return 0;
        }
    }
    if (pt != NULL) {
        double corner[2];
        for (q = 0; q < 4; q++) {
            rect_corner(b, q, corner);
            if (inside_rect(a, corner[0], corner[1])) {
                pt[0] = corner[0];
                pt[1] = corner[1];
                return 1;
            }
        }
        for (q = 0; q < 4; q++) {
            rect_corner(a, q, corner);
            if (inside_rect(b, corner[0], corner[1])) {
                pt[0] = corner[0];
                pt[1] = corner[1];
                return 1;
            }
        }
        if (!edges_cross(a, b, pt)) {
            pt[0] = 0.5 * (a[0] + b[0]); /* not reached for a positive overlap */
            pt[1] = 0.5 * (a[1] + b[1]);
        }
    }
    return 1;
}

int pt_rects_overlap(const double a[5], const double b[5], double pt[2]) {
    return rects_overlap_cs(a, b, cos(a[2]), sin(a[2]), cos(b[2]), sin(b[2]), pt);
}

static void set_violation(PtViolation *v, long k, int body, int other, int reason, double x,
                          double y, double value) {
    v->step = k;
    v->body = body;
    v->other = other;
    v->reason = reason;
    v->x = x;
    v->y = y;
    v->value = value;
}

/* Whether body b (axle midpoint (x, y), heading cos/sin cs, sn) keeps its margin at every one
 * of its points offset[b] .. offset[b+1]-1 (px, py in its frame); else 0 and the first failing
 * point and its distance in out[0..2]. */
static int body_points_clear(const PtChecks *c, const int *offset, const double *px,
                             const double *py, const double *margin, int b, double x, double y,
                             double cs, double sn, double out[3]) {
    int p;
    for (p = offset[b]; p < offset[b + 1]; p++) {
        const double u = x + cs * px[p] - sn * py[p];
        const double v = y + sn * px[p] + cs * py[p];
        const double d = pt_sdf_at(c, u, v);
        if (!(d >= margin[b])) {
            out[0] = u;
            out[1] = v;
            out[2] = d;
            return 0;
        }
    }
    return 1;
}

int pt_check_state(const PtChain *plant, const PtChecks *c, const double *z, long k, double *work,
                   PtViolation *v) {
    const int n = plant->n, nz = 3 + n;
    const double *th = z + 2;
    double *bx = work + RK_STAGES * nz + n, *by = bx + (n + 1), *rects = by + (n + 1);
    double *cs = rects + 5 * (n + 1), *sn = cs + (n + 1);
    int i, b;
    for (i = 0; i < nz; i++) {
        if (!isfinite(z[i])) {
            set_violation(v, k, 0, -1, PT_STOP_NONFINITE, z[0], z[1], 0.0);
            return 1;
        }
    }
    if (c == NULL) {
        return 0;
    }
    for (b = 0; b <= n; b++) {
        cs[b] = cos(th[b]);
        sn[b] = sin(th[b]);
    }
    pt_chain_positions(plant, cs, sn, z[0], z[1], 0, bx, by);
    if (c->nx >= 2 && c->ny >= 2 && c->sdf != NULL) {
        for (b = 0; b <= n; b++) {
            double miss[3];
            if (body_points_clear(c, c->point_offset, c->px, c->py, c->margin, b, bx[b], by[b],
                                  cs[b], sn[b], miss)) {
                continue;
            }
            if (c->fine_offset != NULL &&
                body_points_clear(c, c->fine_offset, c->fine_px, c->fine_py, c->fine_margin, b,
                                  bx[b], by[b], cs[b], sn[b], miss)) {
                continue;
            }
            set_violation(v, k, b, -1, PT_STOP_FOOTPRINT, miss[0], miss[1], miss[2]);
            return 1;
        }
    }
    if (c->phi_max > 0.0) {
        for (i = 1; i <= n; i++) {
            const double phi = pt_wrap(th[i - 1] - th[i]);
            if (fabs(phi) > c->phi_max) {
                set_violation(v, k, i, -1, PT_STOP_JOINT, bx[i], by[i], phi);
                return 1;
            }
        }
    }
    if (c->rect != NULL && n >= 2) {
        for (b = 0; b <= n; b++) {
            const double *r = c->rect + 4 * b;
            double *w = rects + 5 * b;
            w[0] = bx[b] + cs[b] * r[0] - sn[b] * r[1];
            w[1] = by[b] + sn[b] * r[0] + cs[b] * r[1];
            w[2] = th[b];
            w[3] = r[2];
            w[4] = r[3];
        }
        for (b = 0; b <= n; b++) {
            int o;
            for (o = b + 2; o <= n; o++) {
                double pt[2];
                if (rects_overlap_cs(rects + 5 * b, rects + 5 * o, cs[b], sn[b], cs[o], sn[o],
                                     pt)) {
                    set_violation(v, k, b, o, PT_STOP_SELF, pt[0], pt[1], 0.0);
                    return 1;
                }
            }
        }
    }
    return 0;
}

/* ------------------------------------------------------------------ the loop */

int pt_rollout(const PtRollout *r, long *k, double *z, PtControlState *control, long k_end,
               double *work, const PtRecord *record, PtViolation *violation) {
    const PtChain *plant;
    int n, nz, i;
    long row;
    double *phi;
    PtMeasurement m;
    if (r == NULL || k == NULL || z == NULL || control == NULL || work == NULL ||
        violation == NULL || r->plant == NULL || r->controller == NULL || r->reference == NULL) {
        return PT_ERR_ARGUMENT;
    }
    plant = r->plant;
    n = plant->n;
    nz = 3 + n;
    if (n < 1 || r->controller->model.n != n || !(isfinite(r->step) && r->step > 0.0) ||
        !isfinite(r->t_start) || k_end < *k) {
        return PT_ERR_ARGUMENT;
    }
    if (r->checks != NULL && r->checks->nx >= 2 && r->checks->ny >= 2 && r->checks->sdf != NULL &&
        (r->checks->point_offset == NULL || r->checks->px == NULL || r->checks->py == NULL ||
         r->checks->margin == NULL || !(r->checks->h > 0.0))) {
        return PT_ERR_ARGUMENT;
    }
    phi = work + RK_STAGES * nz;
    memset(&m, 0, sizeof(m));
    m.phi = phi;
    set_violation(violation, *k, -1, -1, PT_STOP_NONE, 0.0, 0.0, 0.0);
    if (record != NULL && record->states != NULL) {
        memcpy(record->states, z, sizeof(double) * (size_t)nz);
    }
    if (pt_check_state(plant, r->checks, z, *k, work, violation)) {
        return PT_OK;
    }
    for (row = 0; *k < k_end; row++) {
        const double t = r->t_start + (double)(*k) * r->step;
        PtSample ref;
        double cmd[2];
        int status;
        m.x0 = z[0];
        m.y0 = z[1];
        m.theta0 = z[2];
        for (i = 1; i <= n; i++) {
            phi[i - 1] = z[2 + i - 1] - z[2 + i];
        }
        status = pt_instant(r->controller, control, r->reference, r->leader, t, &m, &ref, cmd,
                            NULL);
        if (status != PT_OK) {
            set_violation(violation, *k, 0, -1, PT_STOP_CONTROL, z[0], z[1], (double)status);
            return PT_OK;
        }
        if (record != NULL) {
            if (record->commands != NULL) {
                record->commands[2 * row] = cmd[0];
                record->commands[2 * row + 1] = cmd[1];
            }
            if (record->references != NULL) {
                record->references[3 * row] = ref.x;
                record->references[3 * row + 1] = ref.y;
                record->references[3 * row + 2] = ref.theta;
            }
            if (record->directions != NULL) {
                record->directions[row] = ref.direction;
            }
        }
        plant_rk4(plant, z, cmd[0], cmd[1], r->step, work);
        *k += 1;
        if (record != NULL && record->states != NULL) {
            memcpy(record->states + (size_t)(row + 1) * (size_t)nz, z, sizeof(double) * (size_t)nz);
        }
        if (pt_check_state(plant, r->checks, z, *k, work, violation)) {
            return PT_OK;
        }
    }
    return PT_OK;
}
