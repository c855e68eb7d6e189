/*
 * The classic fixed-step RK4, written once for the engine: the planner's rollout (rollout.c, the
 * train under a held command) and the pull guide's backward runs (control.c). The readable
 * Python form is tests/reference/ode.py's rk4_step; the arithmetic is the same, in the same order.
 *
 * C99; static inline, so each caller's rates function is inlined into its step.
 */
#ifndef PUSHTRAIN_ODE_H
#define PUSHTRAIN_ODE_H

/* dz/dt at t [s] of the state z (the caller's context says of what) into dz. */
typedef void (*PtRates)(const void *context, double t, const double *z, double *dz);

/* One RK4 step of h [s] (h < 0 runs backward) of the nz values z, in place, from t.
 * work: 5 nz doubles (the four stages, then the stage point). */
static inline void pt_rk4_step(PtRates f, const void *context, double t, double *z, int nz,
                               double h, double *work) {
    double *k1 = work, *k2 = work + nz, *k3 = work + 2 * nz, *k4 = work + 3 * nz;
    double *tmp = work + 4 * nz;
    int i;
    f(context, t, z, k1);
    for (i = 0; i < nz; i++) {
        tmp[i] = z[i] + 0.5 * h * k1[i];
    }
    f(context, t + 0.5 * h, tmp, k2);
    for (i = 0; i < nz; i++) {
        tmp[i] = z[i] + 0.5 * h * k2[i];
    }
    f(context, t + 0.5 * h, tmp, k3);
    for (i = 0; i < nz; i++) {
        tmp[i] = z[i] + h * k3[i];
    }
    f(context, t + h, tmp, k4);
    for (i = 0; i < nz; i++) {
        z[i] = z[i] + h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]);
    }
}

#endif /* PUSHTRAIN_ODE_H */
