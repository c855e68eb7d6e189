/*
 * The fast closed-loop integrator: the controller of control.h in closed loop with the
 * kinematic chain, as core.engine.simulate runs it (its readable twin
 * tests/reference/closed_loop.py), plus optional checks of every body along the way with an
 * early exit at the first violation.
 *
 * Control instants t_k = t_start + k step. At each: sample the last trailer's reference (and,
 * while pulling, the robot's own reference from the leader table), ask pt_command for (v0, w0)
 * with a perfect measurement (robot pose, phi_i = theta_{i-1} - theta_i), hold it over the step
 * (zero-order hold), and integrate the robot (moving along its heading) and the towed trailers
 * (pt_towed_rates, the plant's own chain) with one RK4 step on z = (x0, y0, theta_0..theta_n).
 *
 * The loop is resumable: its whole memory is (k, z, PtControlState), so running instants
 * [k0, k1) and then [k1, k2) gives bit for bit the states of running [k0, k2). The command at
 * the last instant k_end is not computed: it belongs to the next call (which may use a reference
 * extended meanwhile).
 *
 * C99, reentrant, no allocation; every array is the caller's.
 */
#ifndef PUSHTRAIN_ROLLOUT_H
#define PUSHTRAIN_ROLLOUT_H

#include "control.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Why a rollout stopped early (PtViolation.reason). */
enum {
    PT_STOP_NONE = 0,      /* ran to k_end */
    PT_STOP_NONFINITE = 1, /* a state component is NaN or infinite */
    PT_STOP_FOOTPRINT = 2, /* a body's sample point is closer to the blocked space than its margin */
    PT_STOP_JOINT = 3,     /* |phi_i| > phi_max */
    PT_STOP_SELF = 4,      /* two non-adjacent bodies' rectangles overlap */
    PT_STOP_CONTROL = 5    /* the reference, the leader or the controller refused (value: status) */
};

/* Optional checks of every state the loop visits (the entry state and each new one). */
typedef struct {
    /* (a) footprints against a signed distance grid: nx, ny >= 2 (0: no footprint check).
     * sdf[i * nx + j] is the distance [m] to the blocked space (negative inside it) at the grid
     * point (x0 + j h, y0 + i h); bilinear in between; outside the grid (by more than 1e-9 of a
 * cell) nothing is free. */
    int nx, ny;
    const double *sdf;
    double x0, y0, h;
    /* sample points of body b (0 robot .. n) in its own frame (x along the heading, y to the
     * left, from the axle midpoint; the robot's from its centre): indices point_offset[b] ..
     * point_offset[b+1]-1 of px, py. A point is free if the distance there is >= margin[b]. */
    const int *point_offset; /* n + 2 entries */
    const double *px, *py;
    const double *margin;    /* n + 1 entries [m] */
    /* (a') optional second sample set (NULL fine_offset: none), same layout: a body with a point
     * closer than its margin above passes if all of its points here keep fine_margin[b] (e.g. a
     * cover of discs first, a body's perimeter points only where a disc fails). */
    const int *fine_offset;
    const double *fine_px, *fine_py;
    const double *fine_margin;
    /* (b) joint limit: |wrap(theta_{i-1} - theta_i)| <= phi_max; <= 0: no joint check */
    double phi_max;
    /* (c) self-collision of non-adjacent bodies (|a - b| >= 2): rect[4 b .. 4 b + 3] = centre
     * (cx, cy) in the body's frame, half length (along the heading), half width [m]; NULL: no
     * self-collision check. Rectangles that only touch do not collide. */
    const double *rect;
} PtChecks;

/* What the loop runs. */
typedef struct {
    const PtChain *plant;           /* the train's own chain (the controller has its model) */
    const PtController *controller;
    const PtReference *reference;   /* the last trailer's reference */
    const PtLeader *leader;         /* the robot's references while pulling; NULL if no pulls */
    double t_start;                 /* time of instant k = 0 [s] */
    double step;                    /* control and RK4 step [s], > 0 */
    const PtChecks *checks;         /* NULL: no checks (non-finite states still stop the loop) */
} PtRollout;

/* The first violation: at instant `step` (k), body `body` (and `other` for self-collisions),
 * at (x, y) [m]: the sample point (footprint), the body's position (joint, non-finite: the
 * robot's), a point in the overlap (self-collision: a corner of one rectangle inside the other,
 * else a crossing of their edges). `value`: the distance at the point [m] (footprint), phi_i
 * [rad] (joint), the status code (control), 0 otherwise. */
typedef struct {
    long step;
    int body;
    int other;
    int reason;
    double x, y;
    double value;
} PtViolation;

/* Optional per-instant records (NULL to skip any). With k0 the entry instant and k the instant
 * the call returns at, states gets rows k0..k ((k - k0 + 1) x (3 + n)) and the others rows
 * k0..k-1 (one per command): commands (v0, w0), references (x, y, theta of the last trailer's
 * reference sample), directions (its direction). Size them for k_end - k0 (+ 1) rows. */
typedef struct {
    double *states;
    double *commands;
    double *references;
    int *directions;
} PtRecord;

/* Size in bytes of struct number `which` (0 PtChecks, 1 PtRollout, 2 PtViolation, 3 PtRecord),
 * 0 for another number. */
PT_API size_t pt_rollout_sizeof(int which);

/* Doubles of work storage pt_rollout needs for a chain of n trailers. */
PT_API int pt_rollout_work(int n);

/* Run the closed loop from instant *k (state z, controller memory *control) up to instant
 * k_end, or up to the first violation (then *k and z are the violating instant and state, or
 * the instant whose command was refused). On return *k, z and *control are the state to resume
 * from. Returns PT_OK (read violation->reason) or PT_ERR_ARGUMENT / PT_ERR_CAPACITY-style codes
 * for bad setups, leaving everything untouched. */
PT_API int pt_rollout(const PtRollout *r, long *k, double *z, PtControlState *control,
                      long k_end, double *work, const PtRecord *record, PtViolation *violation);

/* The plant alone under a held command: count RK4 steps of h [s] from z (3 + n, advanced in
 * place) with the robot's (v0, w0), each new state into states (count x (3 + n), row-major).
 * The loop's own integrator, for finer samples within a step. work: pt_rollout_work(n)
 * doubles. Returns PT_OK or PT_ERR_ARGUMENT. */
PT_API int pt_hold(const PtChain *plant, double *z, double v0, double w0, double h, int count,
                   double *states, double *work);

/* The checks alone on one state z (3 + n) at instant k (a violation's step is k); returns 1 and
 * fills violation if a check fails, else 0. work: pt_rollout_work(n) doubles. */
PT_API int pt_check_state(const PtChain *plant, const PtChecks *checks, const double *z, long k,
                          double *work, PtViolation *violation);

/* Signed distance [m] at (x, y) from the checks' grid (bilinear); -HUGE_VAL outside it. */
PT_API double pt_sdf_at(const PtChecks *checks, double x, double y);

/* Whether two rectangles (centre, heading, half length, half width) overlap with positive area
 * (separating-axis test); if so and pt is not NULL, a point of the overlap as documented above. */
PT_API int pt_rects_overlap(const double a[5], const double b[5], double pt[2]);

#ifdef __cplusplus
}
#endif

#endif /* PUSHTRAIN_ROLLOUT_H */
