/*
 * The closed-loop work of one communication step of the co-simulation, in one call: the plant's
 * true state -> sensors (sensors.c) -> the control law with its reference and pull leader
 * (pt_track, control.c) -> the push force on the last trailer and the last trailer's tracking
 * errors. The co-simulation master's step loop (cosim/csrc/master_loop.c) keeps only the FMU
 * calls and the recording around it; a slip governor (governor.c) limits the law's command.
 * (A run whose law is written in Python, an open-loop profile, computes the push force and
 * errors in Python, cosim/step_loop.py PythonLaw: an open loop's reference sample is NaN, and
 * the sign of a NaN result depends on how a compiler orders the operands.)
 *
 * C99, reentrant, no allocation; every array is the caller's.
 */
#ifndef PUSHTRAIN_STEP_H
#define PUSHTRAIN_STEP_H

#include "control.h"
#include "governor.h"
#include "sensors.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct {
    PtTrack *track;         /* the law's instant: controller, its state, reference, leader */
    PtSensors *sensors;     /* the sensor model and its play */
    int n_pushes;           /* pushes acting now */
    const double *pushes;   /* (fx [N], fy [N], lateral [N]) each, world frame + lateral */
    double push[2];         /* out: the total force (push_x, push_y) on the last trailer [N] */
    double errors[3];       /* out: the last trailer's true pose against the reference sample,
                             * in its frame: e_lon, e_lat [m], e_theta [rad] (wrapped) */
    PtGovernor *governor;   /* the slip governor on the law's command, or NULL */
    double *governor_work;  /* pt_governor_work(n) doubles (with a governor) */
} PtStep;

/* The pose (x, y [m], theta [rad]) against the reference sample, in the sample's frame:
 * errors = (e_lon, e_lat [m], e_theta [rad], wrapped), the recorder's tracking errors. pt_step
 * computes them for the last trailer's true pose; the controller FMU for its estimated pose. */
PT_API void pt_tracking_errors(const PtSample *sample, double x, double y, double theta,
                               double errors[3]);

/* Size of PtStep in bytes (a binding checks its layout). */
PT_API size_t pt_step_sizeof(void);

/* The step at time t [s] from the true state truth = (x0, y0, theta0, x_n, y_n, theta_n,
 * phi_1..phi_n) with the step's noise (NULL without): the joint readings into phi_meas (n),
 * the measurement, sample and command into s->track (its m.phi is restored), the push force and
 * errors into s. Returns pt_track's status (PT_OK or a PT_ERR_*: then push and errors are not
 * set), or PT_ERR_ARGUMENT for a NULL pointer. */
PT_API int pt_step(PtStep *s, double t, const double *truth, const double *noise,
                   double *phi_meas);

#ifdef __cplusplus
}
#endif

#endif /* PUSHTRAIN_STEP_H */
