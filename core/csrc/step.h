/*
 * The closed-loop work of one communication step of the co-simulation, in one call: the plant's
 * true state -> sensors (sensors.c) -> the control law with its reference and pull leader
 * (pt_track, control.c), or an open-loop profile (openloop.c) -> the push force on the last
 * trailer and the last trailer's tracking errors. The co-simulation master's step loop
 * (cosim/csrc/master_loop.c) keeps only the FMU calls and the recording around it; a slip
 * governor (governor.c) limits the law's command. An open-loop run has no reference: its
 * sample's pose and its errors are NaN, written as the one quiet NaN PT_NO_VALUE (a NaN computed
 * from a NaN pose could carry either sign, depending on how a compiler orders the operands).
 * (A law written in Python, called back from the master's loop, computes the push force and
 * errors in Python, cosim/step_loop.py PythonLaw.)
 *
 * C99, reentrant, no allocation; every array is the caller's.
 */
#ifndef PUSHTRAIN_STEP_H
#define PUSHTRAIN_STEP_H

#include <math.h>

#include "control.h"
#include "governor.h"
#include "openloop.h"
#include "sensors.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct {
    PtTrack *track;         /* the law's instant: controller, its state, reference, leader; or
                             * NULL with a profile */
    const PtProfile *profile; /* an open-loop profile in place of the law, or NULL */
    PtSensors *sensors;     /* the sensor model and its play */
    int n_pushes;           /* pushes acting now */
    const double *pushes;   /* (fx [N], fy [N], lateral [N]) each, world frame + lateral */
    double cmd[2];          /* out: the command sent (v0 [m/s], w0 [rad/s]) */
    PtSample sample;        /* out: the last trailer's reference sample (a profile's: at rest,
                             * pose PT_NO_VALUE) */
    double push[2];         /* out: the total force (push_x, push_y) on the last trailer [N] */
    double errors[3];       /* out: the last trailer's true pose against the reference sample,
                             * in its frame: e_lon, e_lat [m], e_theta [rad] (wrapped); a
                             * profile's: PT_NO_VALUE */
    PtGovernor *governor;   /* the slip governor on the law's command, or NULL (not with a
                             * profile) */
    double *governor_work;  /* pt_governor_work(n) doubles (with a governor) */
} PtStep;

/* The pose (x, y [m], theta [rad]) against the reference sample, in the sample's frame:
 * errors = (e_lon, e_lat [m], e_theta [rad], wrapped), the recorder's tracking errors. pt_step
 * computes them for the last trailer's true pose; the controller FMU for its estimated pose. */
PT_API void pt_tracking_errors(const PtSample *sample, double x, double y, double theta,
                               double errors[3]);

/* The value of a sample's pose and of the errors without a reference: the quiet NaN with
 * the sign bit clear and no payload (bits 0x7ff8000000000000, Python's math.nan). */
#define PT_NO_VALUE ((double)NAN)

/* Size of PtStep in bytes (a binding checks its layout). */
PT_API size_t pt_step_sizeof(void);

/* The step at time t [s] from the true state truth = (x0, y0, theta0, x_n, y_n, theta_n,
 * phi_1..phi_n) with the step's noise (NULL without): the joint readings into phi_meas (n),
 * the command and sample into s->cmd and s->sample (with the law also the measurement, sample
 * and command into s->track, whose m.phi is restored), the push force and errors into s.
 * Returns pt_track's or pt_profile_command's status (PT_OK or a PT_ERR_*: then cmd, push and
 * errors are not set), or PT_ERR_ARGUMENT for a NULL pointer, neither or both of track and
 * profile, or a governor with a profile. */
PT_API int pt_step(PtStep *s, double t, const double *truth, const double *noise,
                   double *phi_meas);

#ifdef __cplusplus
}
#endif

#endif /* PUSHTRAIN_STEP_H */
