/*
 * The co-simulation master's step loop in C: the closed loop of cosim/master.py (_Run.run) for
 * an FMI 2.0 TrailerTrain FMU, run for many communication steps per call.
 *
 * At each communication point t_k = t0 + k step, in the order of the Python loop:
 *   fmi2GetReal of the measured states (robot pose, last trailer's pose, joint angles)
 *   -> pt_step, the engine's closed-loop work (core/csrc/step.c): sensors (backlash, bias,
 *      noise, quantization), reference sample, pull leader, command, the push force of the
 *      active pushes and the tracking errors
 *   -> fmi2SetReal(v_cmd, w_cmd, push_x, push_y) (then, at the first step of a call only, the
 *      slide speeds that change there)
 *   -> fmi2GetReal of every recorded output and fmi2GetBoolean of the flags; the row (in the
 *      layout the caller gives: the result table's columns) gets them, the measured joint
 *      angles, the time, inputs, reference sample and tracking errors
 *   -> jackknife and goal tests -> fmi2DoStep (unless the horizon ends).
 *
 * The FMU is called through its own exported functions (pointers the caller takes from the
 * loaded FMU library). Everything the Python loop does rarely stays in Python: a call returns
 * at the top of a step where an event is due (a bias switch, a push or slide starting or
 * ending), when the caller's step budget is used up, at the goal (a candidate: Python makes the
 * exact test), at a jackknife, at the horizon's end, on a failed FMI call and on a control
 * error. Random noise is drawn by the caller (numpy, in the Python sensors' order) and passed
 * in per step, scaled.
 *
 * C99, reentrant, no allocation: every array is the caller's.
 */
#ifndef PUSHTRAIN_MASTER_LOOP_H
#define PUSHTRAIN_MASTER_LOOP_H

#include <stddef.h>

#include "control.h"
#include "sensors.h"
#include "step.h"

#ifdef __cplusplus
extern "C" {
#endif

/* The FMI 2.0 functions the loop calls (fmi2Component = void *, fmi2ValueReference = unsigned
 * int, fmi2Boolean = int, fmi2Status = int; fmi2Functions.h). */
typedef int (*PtFmi2GetReal)(void *component, const unsigned int *vr, size_t nvr, double *value);
typedef int (*PtFmi2SetReal)(void *component, const unsigned int *vr, size_t nvr,
                             const double *value);
typedef int (*PtFmi2GetBoolean)(void *component, const unsigned int *vr, size_t nvr, int *value);
typedef int (*PtFmi2DoStep)(void *component, double t, double h, int no_set_prior);

/* Why pt_master_run returned (PtMasterLoop.k says at which step). */
enum {
    PT_LOOP_PAUSE = 0,           /* at the top of step k: the budget is used or an event is due */
    PT_LOOP_HORIZON = 1,         /* step k = n_steps recorded: the horizon ended */
    PT_LOOP_JACKKNIFE = 2,       /* step k recorded with the jackknife flag set; no doStep */
    PT_LOOP_GOAL_CANDIDATE = 3,  /* step k recorded, the last trailer within goal_slack of the
                                  * goal's tolerance: the caller decides; no doStep done */
    PT_LOOP_FMI_ERROR = 4,       /* an FMI call of step k failed (failed_call, fmi_status) */
    PT_LOOP_CONTROL_ERROR = 5,   /* pt_step refused step k (control_status); nothing recorded */
    PT_LOOP_ARGUMENT = 6         /* a NULL pointer or a bad size */
};

/* Which FMI call failed (PtMasterLoop.failed_call). */
enum {
    PT_CALL_GET_STATE = 1,
    PT_CALL_SET_INPUTS = 2,
    PT_CALL_SET_SLIDE = 3,
    PT_CALL_GET_OUTPUTS = 4,
    PT_CALL_GET_FLAGS = 5,
    PT_CALL_DO_STEP = 6
};

typedef struct {
    /* ---- the FMU ---- */
    void *component;
    PtFmi2GetReal get_real;
    PtFmi2SetReal set_real;
    PtFmi2GetBoolean get_boolean;
    PtFmi2DoStep do_step;
    const unsigned int *state_vr;  /* n + 6: x[0], y[0], theta[0], x[n], y[n], theta[n], phi[1..n] */
    const unsigned int *input_vr;  /* 4: v_cmd, w_cmd, push_x, push_y */
    const unsigned int *output_vr; /* n_outputs recorded outputs */
    const unsigned int *flag_vr;   /* n + 1: slipping[1..n], jackknifed */
    int n_outputs;
    int n;                         /* trailers */

    /* ---- time ---- */
    double t0, step;               /* t_k = t0 + k step [s] */
    long n_steps;                  /* the last communication point is k = n_steps */

    /* ---- the engine: sensors, control law, pushes ---- */
    PtStep *instant;               /* its track, sensors and the call's active pushes */
    const double *noise_values;    /* noise_per_step values per step (pt_sensors_noise_count),
                                    * from the first step of the call on; NULL without noise */
    int noise_per_step;

    /* ---- recording: where each value goes in a row (indices of row elements) ---- */
    double *rows;                  /* the row of the call's first step; row_width doubles/row */
    int row_width;
    int n_output_runs;             /* the outputs (read into the scratch `outputs`) are copied */
    const int *output_runs;        /* in runs of (first output, first row index, count) */
    const int *flag_at;            /* n + 1: where slipping[1..n] and jackknifed go */
    const int *scalar_at;          /* 15: t, v_cmd, w_cmd, push_x, push_y, slide, x_d, y_d,
                                    * theta_d, v_d, w_d, direction, e_lon, e_lat, e_theta */
    int at_phi_meas;               /* n consecutive: the measured joint angles */
    int at_f_lat_max;              /* n consecutive: copied from f_lat_max into every row */
    const double *f_lat_max;

    /* ---- goal ---- */
    int check_goal;
    double goal_from;              /* the goal is tested from t >= goal_from [s] */
    double goal_x, goal_y, goal_theta;
    double goal_position, goal_heading; /* tolerances [m, rad] */
    double goal_slack;             /* a candidate is within (1 + goal_slack) times them (the
                                    * caller's exact test decides) */

    /* ---- events of the call ---- */
    double pause_at;               /* return at the top of a later step with t >= pause_at */
    double next_bias;              /* return at the top of a later step with
                                    * next_bias <= t + 1e-12 */
    double slide;                  /* the last trailer's slide speed (the row's column) */
    int n_slide_writes;            /* written at the call's first step, after the inputs */
    const unsigned int *slide_vr;
    const double *slide_values;

    /* ---- scratch ---- */
    double *state;                 /* n + 6 */
    double *outputs;               /* n_outputs */
    int *flags;                    /* n + 1 */

    /* ---- out ---- */
    long k;                        /* the step at which the call returned */
    double time;                   /* the FMU's time after its last doStep [s] */
    double inputs[4];              /* the last inputs set */
    int failed_call;               /* PT_CALL_* */
    int failed_slide;              /* PT_CALL_SET_SLIDE: the index of the failed slide write */
    int fmi_status;
    int control_status;
} PtMasterLoop;

/* Size of PtMasterLoop (a binding checks its layout). */
PT_API size_t pt_master_loop_sizeof(void);

/* Run communication steps k = k_first .. (at most) k_stop - 1, k_first <= n_steps, and return
 * the PT_LOOP_* reason; m->k is the step it returned at. Row j of m->rows is step
 * k_first + j, so a call records at most k_stop - k_first rows. */
PT_API int pt_master_run(PtMasterLoop *m, long k_first, long k_stop);

#ifdef __cplusplus
}
#endif

#endif /* PUSHTRAIN_MASTER_LOOP_H */
