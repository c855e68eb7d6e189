/*
 * The backward-motion control law of pushtrain in C99: chain kinematics, Kanayama's law, the
 * controller's command (rest / push / pull, speed and rate limits), the last trailer's line/arc
 * reference and the robot's pulling reference (pull guide).
 *
 * It is the compiled twin of the Python reference implementation (the law in the tests'
 * tests/reference/controller.py, with core/controller.py's settings and diagnostics;
 * core/kinematics.py, core/segment.py, core/reference.py, core/pulling.py): every formula is
 * evaluated in the same order as there, so both give the same numbers
 * (tests/test_native_control.py holds them equal to 1e-12). Self-contained (<math.h>,
 * <string.h>, <stddef.h> only), reentrant (no globals, no allocation: every array is the
 * caller's), so it compiles unchanged into an FMU.
 *
 * Conventions (core/kinematics.py): body 0 is the robot, bodies 1..n the trailers. theta[i] is
 * measured from +x, CCW, and points toward the robot; phi[i-1] = theta[i-1] - theta[i] is joint
 * i (arrays are 0-based: phi[k] is joint k+1). front[k] = F_{k+1}, rear[k] = R_k [m].
 * Pushing (direction +1) moves the last trailer first, v < 0. SI units, radians.
 *
 * Every function that can fail returns a status (PT_OK = 0 or a PT_ERR_* code); nothing aborts.
 */
#ifndef PUSHTRAIN_CONTROL_H
#define PUSHTRAIN_CONTROL_H

#include <stddef.h>

#ifdef __cplusplus
extern "C" {
#endif

#if defined(_WIN32)
#define PT_API __declspec(dllexport)
#elif defined(__GNUC__)
#define PT_API __attribute__((visibility("default")))
#else
#define PT_API
#endif

/* Status codes. */
enum {
    PT_OK = 0,
    PT_ERR_NONFINITE_MEASUREMENT = 1, /* a measured pose or joint angle is NaN or infinite */
    PT_ERR_NONFINITE_COMMAND = 2,     /* the law produced a NaN or infinite command */
    PT_ERR_NO_LEADER = 3,             /* pulling without the robot's reference (leader) */
    PT_ERR_DIRECTION = 4,             /* a reference direction that is not +1, -1 or 0 */
    PT_ERR_ARGUMENT = 5,              /* a NULL pointer, n < 1, a bad size or setting */
    PT_ERR_CAPACITY = 6,              /* the caller's storage is too small */
    PT_ERR_SEGMENT = 7,               /* a segment that Reference refuses (length, kind, ...) */
    PT_ERR_NOT_IN_PULL = 8,           /* a time outside every pulling run of the leader table */
    PT_ERR_EMPTY_REFERENCE = 9        /* sampling a reference without segments */
};

/* Reference directions (core/segment.py PUSH, PULL, REST). */
enum { PT_PULL = -1, PT_REST = 0, PT_PUSH = 1 };

/* Controller modes (ControlInfo.mode). */
enum { PT_MODE_REST = 0, PT_MODE_PUSH = 1, PT_MODE_PULL = 2 };

/* Segment kinds. */
enum { PT_LINE = 0, PT_ARC = 1 };

/* Hitch links of an n-trailer chain: front[k] = F_{k+1}, rear[k] = R_k, k = 0..n-1 [m]. */
typedef struct {
    int n;
    const double *front;
    const double *rear;
} PtChain;

/* One reference sample (core/reference.py ReferenceSample). */
typedef struct {
    double x, y, theta; /* pose [m, m, rad], theta continuous */
    double v, w;        /* signed speed [m/s] (< 0 pushing), yaw rate [rad/s] */
    int direction;      /* PT_PUSH, PT_PULL or PT_REST */
} PtSample;

/* Gains, limits and chain model of the controller (core/controller.py ControllerConfig). */
typedef struct {
    PtChain model;           /* the controller's own chain model */
    double k_x, k_y, k_theta; /* Kanayama gains [1/s, 1/m^2, 1/m] */
    double v_max, w_max;     /* common-factor speed limits [m/s, rad/s] */
    double acc_max;          /* rate limit [m/s^2]; <= 0: none (Python's None) */
    double alpha_max;        /* rate limit [rad/s^2]; <= 0: none */
    double rest_speed;       /* |v_d| at or below which the reference rests [m/s] */
} PtController;

/* The controller's memory: the previous command and its time (for the rate limits). */
typedef struct {
    double v_prev, w_prev; /* [m/s, rad/s] */
    double t_prev;         /* [s], valid if has_t_prev */
    int has_t_prev;        /* 0: the next command is not rate limited (Python's t_prev = None) */
} PtControlState;

/* What the controller is given (cosim.sensors.Measurement). */
typedef struct {
    double x0, y0, theta0;     /* measured robot pose [m, m, rad] */
    const double *phi;         /* n measured joint angles [rad] */
    int has_last;              /* 1: (x_n, y_n, theta_n) is measured directly (last_pose) */
    double x_n, y_n, theta_n;  /* the last trailer's measured pose if has_last */
} PtMeasurement;

/* Diagnostics of one command (core/controller.py ControlInfo). */
typedef struct {
    int mode; /* PT_MODE_* */
    double x_e, y_e, theta_e;
    double x_n, y_n, theta_n;
    double v_ref, w_ref;
    double v_raw, w_raw;
    double scale;
} PtControlInfo;

/* One line or arc of the last trailer's path (core/segment.py Segment). */
typedef struct {
    double length;    /* distance travelled [m], > 0 */
    double curvature; /* d(theta)/ds per metre travelled [1/m]; 0 for a line */
    double speed;     /* |v| [m/s], > 0; 0 takes the reference's default speed */
    int direction;    /* PT_PUSH or PT_PULL */
    int kind;         /* PT_LINE or PT_ARC */
} PtSegment;

/* One phase of a reference: a segment or a cusp dwell (sigma = 0), from time t on. */
typedef struct {
    double t;            /* start time [s] */
    double x, y, theta;  /* pose at t */
    double sigma;        /* sign of v: -direction, 0 at rest */
    double kappa;        /* curvature [1/m] */
    double speed;        /* |v| [m/s] */
} PtPhase;

/* A piecewise line/arc reference (core/reference.py Reference) in the caller's phase storage.
 * Build it with pt_reference_init and pt_reference_append; it can be extended at any time. */
typedef struct {
    PtPhase *phases;
    int capacity;        /* rows of phases */
    int n_phases;
    double t0;           /* time of the start pose [s] */
    double speed;        /* default |v| [m/s] */
    double cusp_dwell;   /* rest at every direction change [s] */
    double t_end;        /* time the last appended segment ends [s] */
    double x_end, y_end, theta_end; /* pose there */
    int last_direction;  /* direction of the last segment (0 before the first) */
} PtReference;

/* The robot's references over the pulling runs (core/pulling.py PullGuide runs), concatenated:
 * rows offset[j] .. offset[j+1]-1 of the columns belong to run j (j = 0..n_runs-1), times
 * ascending within a run and runs in time order. */
typedef struct {
    int n_runs;
    const int *offset;  /* n_runs + 1 entries */
    const double *t, *x, *y, *theta, *v, *w;
} PtLeader;

/* Size in bytes of the struct number `which` (0 PtChain, 1 PtSample, 2 PtController,
 * 3 PtControlState, 4 PtMeasurement, 5 PtControlInfo, 6 PtSegment, 7 PtPhase, 8 PtReference,
 * 9 PtLeader, 10 PtTrack), 0 for another number: lets a binding check its layouts. */
PT_API size_t pt_sizeof(int which);

/* ---- kinematics (core/kinematics.py) ---- */

/* Angle wrapped to (-pi, pi] exactly as kinematics.wrap_scalar (Python's float modulo). */
PT_API double pt_wrap(double angle);

/* Axle-midpoint positions x[0..n], y[0..n] [m] of every body from one body's position and the
 * cos and sin of every heading, cs[0..n], sn[0..n]: the robot's (x_a, y_a) (from_last = 0) or
 * the last trailer's (from_last = 1). P_i = P_{i-1} - R_{i-1} e_{i-1} - F_i e_i; each body's
 * offset from the anchor is summed link by link outward from the anchor, then added to the
 * anchor's position. The one definition of the bodies' positions (kinematics.body_positions
 * is its Python face): the planner's checks, the pull guide and the controller's estimate of
 * the last trailer call it. */
PT_API void pt_chain_positions(const PtChain *chain, const double *cs, const double *sn,
                               double x_a, double y_a, int from_last, double *x, double *y);

/* pt_chain_positions for `rows` states: headings theta (rows, n+1), anchors x_a, y_a (rows,),
 * out x, y (rows, n+1); work holds 2 (n+1) doubles. */
PT_API void pt_body_positions(const PtChain *chain, long rows, const double *theta,
                              const double *x_a, const double *y_a, int from_last, double *x,
                              double *y, double *work);

/* The last trailer's pose (x_n, y_n, theta_n) from the robot pose and the n joint angles
 * (BackwardController.last_trailer_pose); theta_i = theta_{i-1} - phi_i (theta_n = theta0 -
 * sum(phi), not wrapped), the position by pt_chain_positions. */
PT_API void pt_last_trailer_pose(const PtChain *chain, double x0, double y0, double theta0,
                                 const double *phi, double pose[3]);

/* Robot (v0, w0) that makes the last trailer move with (v_n, w_n) (inverse map, Eq. 5;
 * kinematics.robot_velocity_from_last). */
PT_API void pt_robot_velocity_from_last(const PtChain *chain, const double *phi, double v_n,
                                        double w_n, double out[2]);

/* Yaw rates w[0..n] of every body when the last trailer moves with (v_n, w_n) and the headings
 * are theta[0..n] (pulling.rates_driven_by_last, i.e. kinematics.velocities_from_last). */
PT_API void pt_rates_from_last(const PtChain *chain, const double *theta, double v_n,
                               double w_n, double *w);

/* Yaw rates w[0..n] of every body towed by the robot's (v0, w0) with headings theta[0..n]
 * (forward map; planner.train_check.towed_rates). */
PT_API void pt_towed_rates(const PtChain *chain, const double *theta, double v0, double w0,
                           double *w);

/* ---- the control law (tests/reference/controller.py BackwardController) ---- */

/* Kanayama's law (Eq. 3-4): out = (u_d cos th_e + K_x x_e, w_d + u_d (K_y y_e + K_th sin th_e)). */
PT_API void pt_kanayama(const PtController *c, double x_e, double y_e, double th_e, double u_d,
                        double w_d, double out[2]);

/* Forget the history: the previous command is (v0, w0), at time t if has_t (else the next
 * command is not rate limited). BackwardController.reset. */
PT_API void pt_control_reset(PtControlState *state, double v0, double w0, double t, int has_t);

/* Record the command actually sent after an outer limiter (BackwardController.sent). */
PT_API void pt_control_sent(PtControlState *state, double v0, double w0);

/* The robot command cmd = (v0, w0) at time t for the measurement and the last trailer's
 * reference sample ref; leader is the robot's own reference while pulling (NULL otherwise).
 * Updates state (the rate limits' memory) on success only. info may be NULL.
 * BackwardController.command, except that every non-finite measured value (not only the
 * last trailer's pose) and every non-finite raw command is refused. */
PT_API int pt_command(const PtController *c, PtControlState *state, double t,
                      const PtMeasurement *m, const PtSample *ref, const PtSample *leader,
                      double cmd[2], PtControlInfo *info);

/* ---- the reference (core/reference.py) ---- */

/* Start a reference at pose start = (x, y, theta) at time t0 with the default speed [m/s] and
 * cusp dwell [s] in the caller's storage of capacity phases. previous_direction is the
 * direction of the motion before t0 (0: none); a first segment of the other direction then
 * starts with a dwell, as it would inside one longer reference. A reference needs at most
 * 2 phases per segment. */
PT_API int pt_reference_init(PtReference *r, PtPhase *storage, int capacity,
                             const double start[3], double speed, double cusp_dwell, double t0,
                             int previous_direction);

/* Append one segment (Reference.from_segments' table, row by row). */
PT_API int pt_reference_append(PtReference *r, const PtSegment *segment);

/* The reference at time t (Reference.sample_at). */
PT_API int pt_reference_sample(const PtReference *r, double t, PtSample *out);

/* Start and end times of every maximal pulling run (Reference.pull_intervals); returns how many
 * there are (the first capacity are written), or -PT_ERR_ARGUMENT. */
PT_API int pt_reference_pull_intervals(const PtReference *r, double *t_a, double *t_b,
                                       int capacity);

/* pt_reference_sample at each of the count times t into x, y, theta, v, w and direction (the
 * arrays of Reference.sample and direction_at). Returns PT_OK or the first failure's status. */
PT_API int pt_reference_samples(const PtReference *r, const double *t, int count, double *x,
                                double *y, double *theta, double *v, double *w, int *direction);

/* ---- the pull guide (core/pulling.py) ---- */

/* Rows of the backward run over [t_a, t_b] with RK4 step `step` (PullGuide: the run's K), or
 * -PT_ERR_ARGUMENT. */
PT_API int pt_pull_run_rows(double t_a, double t_b, double step);

/* Doubles of work storage pt_pull_run needs for a chain of n trailers. */
PT_API int pt_pull_run_work(int n);

/* The robot's reference over the pulling run [t_a, t_b] of ref (core/pulling.py PullGuide;
 * readable in tests/reference/pulling.py): the chain drawn out straight at t_b, driven backward
 * in time by the last trailer's reference with RK4 of step `step`. Writes
 * pt_pull_run_rows(...) rows, times ascending, into t, x, y, theta, v, w and, if not NULL, the
 * headings (rows x (n+1), row-major). work: pt_pull_run_work(n) doubles. */
PT_API int pt_pull_run(const PtChain *model, const PtReference *ref, double t_a, double t_b,
                       double step, double *work, double *t, double *x, double *y, double *theta,
                       double *v, double *w, double *headings);

/* A reference given by its sampling function: the sample at t [s] of `source` into out. */
typedef int (*PtSampler)(const void *source, double t, PtSample *out);

/* pt_pull_run of a reference given by its sampling function (a sampled reference). */
PT_API int pt_pull_run_sampled(const PtChain *model, PtSampler sample, const void *source,
                               double t_a, double t_b, double step, double *work, double *t,
                               double *x, double *y, double *theta, double *v, double *w,
                               double *headings);

/* The robot's reference at t from a leader table (PullGuide.sample_at); direction PT_PULL. */
PT_API int pt_leader_sample(const PtLeader *leader, double t, PtSample *out);

/* ---- one control instant (core/tracking.py TrackingLoop.command) ---- */

/* The step sequence of one control instant, written once for the co-simulation (pt_track), the
 * planner's rollout (rollout.c) and the controller FMU (ctrl_model.c): sample the last
 * trailer's reference at t into *sample, while pulling the robot's own from the leader table
 * (NULL: none; pt_command then refuses a pulling instant), and command (v0, w0) into cmd for
 * the measurement m (info may be NULL). Returns pt_reference_sample's or pt_leader_sample's
 * status if one fails, else pt_command's. */
PT_API int pt_instant(const PtController *c, PtControlState *state, const PtReference *reference,
                      const PtLeader *leader, double t, const PtMeasurement *m,
                      PtSample *sample, double cmd[2], PtControlInfo *info);

/* Everything one control instant reads and writes, so that a binding makes one call with one
 * argument per instant: set t and m (t, m.x0, m.y0, m.theta0 are four consecutive doubles),
 * call pt_track, read sample and cmd (consecutive: a sample, then the two commands). */
typedef struct {
    const PtController *controller;
    PtControlState *state;
    const PtReference *reference; /* the last trailer's reference */
    const PtLeader *leader;       /* the robot's reference while pulling; NULL: never pulls */
    double t;                     /* [s] */
    PtMeasurement m;
    PtSample sample;              /* out: the reference of the last trailer at t */
    double cmd[2];                /* out: (v0, w0) [m/s, rad/s] */
    PtControlInfo info;           /* out: the command's diagnostics */
} PtTrack;

/* The last trailer's reference at k->t into k->sample, the robot's reference from k->leader
 * while that sample pulls, then pt_command into k->cmd and k->info. Returns the status of
 * pt_reference_sample or pt_leader_sample if one fails, else pt_command's. */
PT_API int pt_track(PtTrack *k);

#ifdef __cplusplus
}
#endif

#endif /* PUSHTRAIN_CONTROL_H */
