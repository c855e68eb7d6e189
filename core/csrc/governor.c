/*
 * The slip-aware speed governor (governor.h): core/governor.py's lateral_forces and
 * SlipGovernor.limit in the same order of operations.
 */
#include "governor.h"

#include <math.h>

size_t pt_governor_sizeof(void) { return sizeof(PtGovernor); }

int pt_governor_work(int n) { return 7 * (n + 1) + 1; }

static double clamp(double value, double lo, double hi) {
    /* min(max(value, lo), hi) as Python evaluates it */
    const double a = (lo > value) ? lo : value;
    return (hi < a) ? hi : a;
}

/* governor.lateral_forces: |F_i| <= limits_i for every trailer? */
static int within_limits(const PtGovernor *g, const double *c, const double *s, double v0,
                         double w0, double dv0, double dw0, double *work) {
    const int n = g->model.n;
    const double *front = g->model.front, *rear = g->model.rear;
    double *v = work, *w = work + (n + 1), *dv = work + 2 * (n + 1), *dw = work + 3 * (n + 1);
    double next_e = 0.0, next_n = 0.0;
    int i;
    v[0] = v0;
    w[0] = w0;
    dv[0] = dv0;
    dw[0] = dw0;
    for (i = 1; i <= n; i++) {
        const double r = rear[i - 1], f = front[i - 1], ci = c[i - 1], si = s[i - 1];
        const double vi = ci * v[i - 1] + r * si * w[i - 1];
        const double wi = (si * v[i - 1] - r * ci * w[i - 1]) / f;
        const double phidot = w[i - 1] - wi;
        dv[i] = -si * phidot * v[i - 1] + ci * dv[i - 1] + ci * phidot * r * w[i - 1] +
                si * r * dw[i - 1];
        dw[i] = (ci * phidot * v[i - 1] + si * dv[i - 1] + si * phidot * r * w[i - 1] -
                 ci * r * dw[i - 1]) / f;
        v[i] = vi;
        w[i] = wi;
    }
    for (i = n; i >= 1; i--) {
        double rear_link, f_n, f_e, force;
        if (i < n) { /* rotate f_{i+1} from frame i+1 into frame i (angle -phi_{i+1}) */
            const double cp = c[i], sp = s[i];
            const double e = next_e * cp + next_n * sp;
            const double nn = -next_e * sp + next_n * cp;
            next_e = e;
            next_n = nn;
        }
        rear_link = (i < n) ? rear[i] : 0.0;
        f_n = (g->inertia[i - 1] * dw[i] - rear_link * next_n) / front[i - 1];
        f_e = g->mass[i - 1] * dv[i] + next_e;
        force = g->mass[i - 1] * v[i] * w[i] - f_n + next_n;
        if (!(fabs(force) <= g->limits[i - 1])) {
            return 0;
        }
        next_e = f_e;
        next_n = f_n;
    }
    return 1;
}

/* SlipGovernor.limit's within(scale). */
static int within(const PtGovernor *g, const double *c, const double *s, double v_cmd,
                  double w_cmd, double scale, double *work) {
    const double v = g->v_prev + scale * (v_cmd - g->v_prev);
    const double w = g->w_prev + scale * (w_cmd - g->w_prev);
    const double dv = clamp((v - g->v_est) / g->tau, -g->acc_max, g->acc_max);
    const double dw = clamp((w - g->w_est) / g->tau, -g->alpha_max, g->alpha_max);
    return within_limits(g, c, s, g->v_est, g->w_est, dv, dw, work);
}

void pt_governor_limit(PtGovernor *g, const double *phi, double *v_io, double *w_io,
                       double *work) {
    const int n = g->model.n;
    const double v_cmd = *v_io, w_cmd = *w_io;
    double *c = work + 4 * (n + 1), *s = work + 5 * (n + 1);
    double scale = 1.0, v_out, w_out, decay;
    int i;
    for (i = 0; i < n; i++) {
        c[i] = cos(phi[i]);
        s[i] = sin(phi[i]);
    }
    if (!within(g, c, s, v_cmd, w_cmd, 1.0, work)) {
        g->limited += 1;
        if (!within(g, c, s, v_cmd, w_cmd, 0.0, work)) {
            scale = 0.0;
            g->saturated += 1;
        } else {
            double lo = 0.0, hi = 1.0;
            int k;
            for (k = 0; k < 30; k++) {
                const double mid = 0.5 * (lo + hi);
                if (within(g, c, s, v_cmd, w_cmd, mid, work)) {
                    lo = mid;
                } else {
                    hi = mid;
                }
            }
            scale = lo;
        }
    }
    v_out = g->v_prev + scale * (v_cmd - g->v_prev);
    w_out = g->w_prev + scale * (w_cmd - g->w_prev);
    decay = 1.0 - exp(-g->dt / g->tau);
    g->v_est += clamp((v_out - g->v_est) * decay, -g->acc_max * g->dt, g->acc_max * g->dt);
    g->w_est += clamp((w_out - g->w_est) * decay, -g->alpha_max * g->dt, g->alpha_max * g->dt);
    g->v_prev = v_out;
    g->w_prev = w_out;
    *v_io = v_out;
    *w_io = w_out;
}
