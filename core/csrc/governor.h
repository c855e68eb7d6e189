/*
 * The slip-aware speed governor (core/governor.py SlipGovernor's limit, its readable form; the
 * tests hold the two equal bit for bit): the command change the robot may make so that the
 * lateral wheel forces its own model predicts stay within a share of friction.
 *
 * C99, reentrant, no allocation; every array is the caller's.
 */
#ifndef PUSHTRAIN_GOVERNOR_H
#define PUSHTRAIN_GOVERNOR_H

#include "control.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct {
    PtChain model;          /* the controller's chain */
    const double *mass;     /* n: trailer masses with payload [kg] */
    const double *inertia;  /* n: yaw inertias about the axle [kg m^2] */
    const double *limits;   /* n: allowed |F_d,i| [N] */
    double tau, acc_max, alpha_max; /* the robot's velocity loop as modelled [s, m/s^2, rad/s^2] */
    double dt;              /* control period [s] */
    /* memory */
    double v_est, w_est, v_prev, w_prev;
    long saturated, limited;
} PtGovernor;

/* Size of PtGovernor (a binding checks its layout). */
PT_API size_t pt_governor_sizeof(void);

/* Doubles of work storage pt_governor_limit needs for n trailers. */
PT_API int pt_governor_work(int n);

/* The command to send instead of (*v, *w) given measured joint angles phi (n), written back into
 * *v, *w; advances the governor's robot-velocity estimate by dt. */
PT_API void pt_governor_limit(PtGovernor *g, const double *phi, double *v, double *w,
                              double *work);

#ifdef __cplusplus
}
#endif

#endif /* PUSHTRAIN_GOVERNOR_H */
