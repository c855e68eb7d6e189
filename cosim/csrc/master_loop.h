/*
 * The co-simulation master's step loop in C (cosim/master.py's one loop): a TrailerTrain FMU,
 * FMI 2.0 or 3.0, stepped with the controller in the loop for many communication steps per call.
 *
 * At each communication point t_k = t0 + k step:
 *   get the measured states (robot pose, last trailer's pose, joint angles)
 *   -> the step's closed-loop work: either pt_step, the engine (core/csrc/step.c: sensors,
 *      reference sample, pull leader, command with the slip governor, or an open-loop
 *      profile's command; push force, tracking errors), or the caller's command hook (a law
 *      written in Python, a sampled reference), which fills hook_out and hook_phi
 *   -> set (v_cmd, w_cmd, push_x, push_y)
 *   -> get every recorded output and the flags; the row (the result table's columns) gets
 *      them, the measured joint angles, the time, inputs, reference sample and tracking errors
 *   -> jackknife and goal tests -> doStep (unless the horizon ends).
 *
 * The FMU is called through its own exported functions (pointers the caller takes from the
 * loaded FMU library). FMI 3.0 reads array variables whole: a read names value references, the
 * number of values they hold, and where each named value is among them (a gather index).
 * A call returns at the top of a step where an event is due (a bias switch, a push or slide
 * starting or ending: the caller applies it), when the caller's step budget is used up, at a
 * goal candidate (the caller makes the exact test), at a jackknife, at the horizon's end, on a
 * failed FMI call and on a refused control instant. Random noise is drawn by the caller and
 * passed in per step, scaled.
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

/* Why pt_master_run returned (PtMasterLoop.k says at which step). */
enum {
    PT_LOOP_PAUSE = 0,           /* at the top of step k: the budget is used or an event is due */
    PT_LOOP_HORIZON = 1,         /* step k = n_steps recorded: the horizon ended */
    PT_LOOP_JACKKNIFE = 2,       /* step k recorded with the jackknife flag set; no doStep */
    PT_LOOP_GOAL_CANDIDATE = 3,  /* step k recorded, the last trailer within goal_slack of the
                                  * goal's tolerance: the caller decides; no doStep done */
    PT_LOOP_FMI_ERROR = 4,       /* an FMI call of step k failed (failed_call, fmi_status) */
    PT_LOOP_CONTROL_ERROR = 5,   /* the control instant of step k was refused (control_status);
                                  * nothing recorded */
    PT_LOOP_ARGUMENT = 6         /* a NULL pointer or a bad size */
};

/* Which FMI call failed (PtMasterLoop.failed_call). */
enum {
    PT_CALL_GET_STATE = 1,
    PT_CALL_SET_INPUTS = 2,
    PT_CALL_GET_OUTPUTS = 4,
    PT_CALL_GET_FLAGS = 5,
    PT_CALL_DO_STEP = 6
};

/* The values the command hook writes into hook_out (and pt_step's equivalents). */
enum {
    PT_OUT_V_CMD, PT_OUT_W_CMD, PT_OUT_PUSH_X, PT_OUT_PUSH_Y, PT_OUT_X_D, PT_OUT_Y_D,
    PT_OUT_THETA_D, PT_OUT_V_D, PT_OUT_W_D, PT_OUT_DIRECTION, PT_OUT_E_LON, PT_OUT_E_LAT,
    PT_OUT_E_THETA, PT_OUT_COUNT
};

/* One FMU read: nvr value references holding count values; value j of the n_named values read
 * is values[index[j]] (index NULL: j). values is the caller's scratch of count doubles (Reals)
 * or count ints (Booleans; FMI 3.0's are one byte each, read from its start). */
typedef struct {
    const unsigned int *vr;
    int nvr;
    int count;
    const int *index;
    int n_named;
    void *values;
} PtFmuRead;

/* A law written by the caller: given the step's time t [s] (the true state in PtMasterLoop.state)
 * it fills hook_out (PT_OUT_COUNT values) and hook_phi (n joint readings); nonzero refuses the
 * instant (the caller keeps why). */
typedef int (*PtCommandHook)(void *user, double t);

typedef struct {
    /* ---- the FMU ---- */
    void *component;
    int fmi_version;               /* 2 or 3 */
    void *get_real, *set_real, *get_boolean, *do_step; /* fmi2GetReal.. or fmi3GetFloat64.. */
    PtFmuRead state;               /* n + 6: x[0], y[0], theta[0], x[n], y[n], theta[n],
                                    * phi[1..n]; gathered into `truth` */
    PtFmuRead outputs;             /* the recorded outputs, to row[output_at[j]] */
    PtFmuRead flags;               /* n + 1: slipping[1..n], jackknifed, to row[flag_at[j]] */
    const unsigned int *input_vr;  /* 4 scalars: v_cmd, w_cmd, push_x, push_y */
    int n;                         /* trailers */

    /* ---- time ---- */
    double t0, step;               /* t_k = t0 + k step [s] */
    long n_steps;                  /* the last communication point is k = n_steps */

    /* ---- the step's closed-loop work: the engine, or the caller's hook ---- */
    PtStep *engine;                /* its law (track) or open-loop profile, sensors and the
                                    * call's active pushes; or NULL */
    const double *noise_values;    /* engine: noise_per_step values per step from the call's
                                    * first step on (pt_sensors_noise_count); NULL without */
    int noise_per_step;
    PtCommandHook hook;            /* without engine */
    void *hook_user;
    double *hook_out;              /* PT_OUT_COUNT */
    double *hook_phi;              /* n */

    /* ---- recording: where each value goes in a row (indices of row elements) ---- */
    double *rows;                  /* the row of the call's first step; row_width doubles/row */
    int row_width;
    const int *output_at;          /* outputs.n_named */
    const int *flag_at;            /* n + 1 */
    const int *scalar_at;          /* 15: t, v_cmd, w_cmd, push_x, push_y, slide, x_d, y_d,
                                    * theta_d, v_d, w_d, direction, e_lon, e_lat, e_theta */
    int at_phi_meas;               /* n consecutive: the measured joint angles */
    int at_f_lat_max;              /* n consecutive: copied from f_lat_max into every row */
    const double *f_lat_max;
    double slide;                  /* the last trailer's slide speed (the row's column) */

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

    /* ---- scratch ---- */
    double *truth;                 /* n + 6: the measured states in the order above */

    /* ---- out ---- */
    long k;                        /* the step at which the call returned */
    double time;                   /* the FMU's time after its last doStep [s] */
    double inputs[4];              /* the last inputs set */
    int failed_call;               /* PT_CALL_* */
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
