/*
 * TrailerTrain: a holonomic robot with n passive off-hooked trailers (the plant of pushtrain).
 *
 * Bodies i = 0..n: 0 is the robot, 1..n the trailers. Headings theta[i] from +x, CCW positive,
 * pointing toward the robot. The number of trailers n is data of the instance (ModelData.n):
 * fixed by the build for FMI 2.0 (MAX_TRAILERS = n), a structural parameter up to MAX_TRAILERS
 * for FMI 3.0. The physics (chain kinematics, accelerations, lateral wheel forces, integration)
 * lives in chain.c, forces.c, slip.c, slip_solver.c and model.c, the start values in start.c,
 * access to the variables by value reference in variables.c; none of them knows the FMI version.
 * The glue is fmi2.c or fmi3.c over instance.c, through the model interface of fmu_model.h
 * (model.c, start.c and variables.c implement it). The derivations are in the comments of chain.c,
 * forces.c, slip.c and slip_solver.c. The files call one another one way, never in a circle:
 *   model.c -> {variables.c, slip.c, slip_solver.c, forces.c, chain.c}
 *   variables.c -> start.c      slip.c -> {slip_solver.c, forces.c, chain.c}
 *   slip_solver.c -> {forces.c, chain.c}      forces.c -> chain.c
 */
#ifndef TRAILERTRAIN_MODEL_H
#define TRAILERTRAIN_MODEL_H

/* the model interface of the glue; it includes the generated build_config.h: FMI_VERSION,
   MODEL_IDENTIFIER, MODEL_GUID, MODEL_HEADER, and MAX_TRAILERS, DEFAULT_TRAILERS */
#include "fmu_model.h"

#if !defined(MAX_TRAILERS) || MAX_TRAILERS < 1 || MAX_TRAILERS > 50
#error "MAX_TRAILERS must be defined in build_config.h as 1..50"
#endif
#if !defined(DEFAULT_TRAILERS) || DEFAULT_TRAILERS < 1 || DEFAULT_TRAILERS > MAX_TRAILERS
#error "DEFAULT_TRAILERS must be defined in build_config.h as 1..MAX_TRAILERS"
#endif

#define MAX_BODIES (MAX_TRAILERS + 1)  /* array size of the per-body quantities */
#define MAX_STATE (MAX_TRAILERS + 5)   /* x0, y0, v0, w0, theta[0..n] */
#define IX_X0 0
#define IX_Y0 1
#define IX_V0 2
#define IX_W0 3
#define IX_THETA 4                     /* theta[i] at IX_THETA + i */
#define N_STATE(m) ((m)->n + 5)        /* the state's length for the instance's n */

static inline double pt_clamp(double value, double lo, double hi) {
    return value < lo ? lo : (value > hi ? hi : value);
}

/* Everything an instance computes with. Plain data without pointers, so an FMU state is a copy.
   Per-body arrays hold index i = 0..n; the elements beyond n are zero and never read. */
#define MODEL_CAN_GET_AND_SET_STATE 1
struct ModelData {
    int n;                          /* number of trailers, 1..MAX_TRAILERS */
    int n_bodies_set;               /* FMI 3.0: n_bodies as set (0: not set since checked) */

    /* parameters */
    double front[MAX_BODIES];       /* F_i, i = 1..n [m] */
    double rear[MAX_BODIES];        /* R_i, i = 0..n-1 [m] */
    double mass[MAX_BODIES];        /* [kg] */
    double inertia[MAX_BODIES];     /* about the axle midpoint [kg m^2] */
    double payload[MAX_BODIES];     /* point mass at the axle midpoint [kg] */
    double mu[MAX_BODIES];          /* lateral friction coefficient [-] */
    double theta_start[MAX_BODIES]; /* [rad] */
    double g, robot_tau, robot_acc_max, robot_alpha_max, phi_max;
    double x0_start, y0_start, v_start, w_start, max_substep;
    double slip_substep;            /* substep while some wheel slides (slip_mode 1) [s] */
    int slip_mode;

    /* inputs */
    double v_cmd, w_cmd, push_x, push_y;
    double slide[MAX_BODIES];       /* imposed lateral sliding speed u_i [m/s], i = 1..n */

    /* continuous state and time */
    double time;
    double q[MAX_STATE];
    /* slip_mode 1: while some wheel slides ("dynamic" regime) the trailer yaw rates are states */
    bool dynamic;
    double wt[MAX_BODIES];          /* trailer yaw rates [rad/s], valid when dynamic */
    double alpha_dyn[MAX_BODIES];   /* trailer yaw accelerations, last dynamic substep [rad/s^2] */
    double f_dyn[MAX_BODIES];       /* lateral wheel forces of the last dynamic substep [N] */

    /* outputs, valid when outputs_valid */
    bool outputs_valid;
    double x[MAX_BODIES], y[MAX_BODIES], phi[MAX_BODIES], v[MAX_BODIES], w[MAX_BODIES];
    double F_lat[MAX_BODIES], F_lat_max[MAX_BODIES], hitch_fx[MAX_BODIES], hitch_fy[MAX_BODIES];
    double slide_speed[MAX_BODIES]; /* lateral sliding speed of wheel i along n_i [m/s] */
    bool slipping[MAX_BODIES];
    bool jackknifed;
};

/* start.c (besides its part of fmu_model.h: model_set_defaults puts every variable at its start
   value, with n = DEFAULT_TRAILERS) */
/* n trailers (1..MAX_TRAILERS, checked by the caller): the per-body parameters and inputs return
   to their start values, sized for the new n (FMI 3.0: a dimension change invalidates them). */
PT_INTERNAL void model_set_trailers(ModelData *m, int n);
PT_INTERNAL void model_state_from_start(ModelData *m);
/* model.c */
/* variables.c: checks every parameter against its range (the bounds of pushtrain/limits.py,
   generated into variables.h) and for finiteness; on failure writes "name = value: allowed lo to
   hi unit (reason)" into msg and returns false. */
PT_INTERNAL bool model_check_parameters(const ModelData *m, char *msg, size_t len);
/* Checks combinations of values that are each valid alone (slip_mode and the slide inputs), once,
   when initialization ends: importers set start values in any order. Same contract as above. */
PT_INTERNAL bool model_check_combinations(const ModelData *m, char *msg, size_t len);
PT_INTERNAL void model_compute_outputs(ModelData *m);
PT_INTERNAL bool model_state_is_finite(const ModelData *m);
PT_INTERNAL bool model_outputs_are_finite(const ModelData *m);
/* Integrates from m->time to m->time + h with fixed RK4 substeps; sets m->time = t_end. */
PT_INTERNAL void model_integrate(ModelData *m, double h, double t_end);

/* variables.c (besides its part of fmu_model.h): the numbering, names, types and causalities
   of the variables are generated from fmu/variables.py (variables.h, included by variables.c
   only); what can be set depends on the phase. */
PT_INTERNAL const char *model_variable_name(const ModelData *m, unsigned vr, char *buffer,
                                            size_t len);
PT_INTERNAL bool model_get_real(const ModelData *m, unsigned vr, double values[], size_t n_values,
                                size_t *index, char *msg, size_t len);

/* chain.c */
/* Velocities of all bodies: v[i], w[i] and cos/sin of phi_i (index 1..n). */
PT_INTERNAL void chain_velocities(const ModelData *m, const double *q, double *c, double *s,
                                  double *v, double *w);
/* Time derivative of the state. */
PT_INTERNAL void chain_derivatives(const ModelData *m, const double *q, double *dq);
/* Robot accelerations (dv0, dw0) commanded by the velocity loop at state q. */
PT_INTERNAL void robot_accelerations(const ModelData *m, const double *q, double *dv0,
                                     double *dw0);
/* Longitudinal and yaw accelerations of all bodies (index 0..n) from the robot's. */
PT_INTERNAL void chain_accelerations(const ModelData *m, const double *c, const double *s,
                                     const double *v, const double *w, double dv0, double dw0,
                                     double *dv, double *dw);
/* One classical RK4 step of the rolling (kinematic) model. */
PT_INTERNAL void model_rk4_step(const ModelData *m, double *q, double dt);
/* Robot rear hitch: velocity vh and acceleration ah (world) at state q. */
PT_INTERNAL void robot_hitch(const ModelData *m, const double *q, double *vh, double *ah);
/* RK4 of the robot alone over dt [s] (its motion does not depend on the trailers). */
PT_INTERNAL void robot_rk4(const ModelData *m, double *q, double dt);

/* forces.c */
/* Newton-Euler from trailer n down to 1 for rolling wheels at headings q: lateral wheel forces
   (F_lat) and hitch forces (world frame) into the given arrays (index 1..n). */
PT_INTERNAL void lateral_forces(const ModelData *m, const double *q, const double *v,
                                const double *w, const double *dv, const double *dw,
                                double *F_lat, double *hitch_fx, double *hitch_fy);
/* Can every wheel roll at state q with the current inputs? (the force rolling needs is within
   friction) */
PT_INTERNAL bool slip_wheels_roll(const ModelData *m, const double *q);

/* slip.c (slip_mode 1) */
/* One substep within the t_left [s] still to go: kinematic RK4 (at most max_substep) while every
   wheel can roll at its start and end, else velocity-level time stepping with Coulomb friction
   impulses (at most slip_substep). *rolls: every wheel is known to roll at the current state with
   the current inputs (updated). Returns the substep taken. */
PT_INTERNAL double slip_advance(ModelData *m, double t_left, bool *rolls);

/* slip_solver.c (slip_mode 1): the friction solver of the dynamic regime, in linear time (the
   tests build their dense reference, tests/csrc/slip_dense.c, in its place) */
#define STICK_SPEED 1e-7 /* |u| below this counts as rolling when leaving the dynamic regime */
#define CONFIG_ITERATIONS 8       /* fixed-point iterations on the end-of-substep headings */
#define CONFIG_TOLERANCE 1e-12    /* [rad] end headings converged: |u| error <= speed * 1e-12 */
/* One substep of dt [s] of the dynamic regime; the friction impulses make the lateral wheel
   speeds consistent at the end of the substep. Leaves the regime when every wheel sticks and can
   roll at the new state. */
PT_INTERNAL void slip_dynamic_step(ModelData *m, double dt);
/* Outputs of the dynamic regime: velocities, sliding speeds, wheel and hitch forces. */
PT_INTERNAL void slip_outputs(ModelData *m);
/* Force outputs at the onset of sliding: the state rolls but rolling would need more than
   friction with the current inputs; F_lat and the hitch forces become the Coulomb forces of that
   instant (the velocity outputs stay those of rolling). */
PT_INTERNAL void slip_onset_outputs(ModelData *m);

#endif
