/*
 * Open-loop robot command profiles (core/openloop.py): the command (v0 [m/s], w0 [rad/s]) as a
 * function of time alone, given as a table of pieces. From its start time on, each channel of
 * a piece ramps from its start value at its rate and holds once it reaches its stop value (a
 * rate of 0 holds the start value). A periodic profile repeats its pieces every period from
 * t = 0 (t taken modulo the period as Python's divmod does) and may flip the sign of a channel
 * every other period; the command is 0 before t = 0 and before the first piece. The master's
 * step (step.c, pt_step) runs it in place of the law, so an open-loop run makes no call back
 * into Python.
 *
 * C99, reentrant, no allocation; every array is the caller's.
 */
#ifndef PUSHTRAIN_OPENLOOP_H
#define PUSHTRAIN_OPENLOOP_H

#include "control.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Channels of a command and the bits of PtProfile.flip. */
enum { PT_PROFILE_V = 0, PT_PROFILE_W = 1 };
enum { PT_FLIP_V = 1, PT_FLIP_W = 2 };

/* One piece of a profile, from time t [s] (within the period) on; index 0 is v, 1 is w. */
typedef struct {
    double t;        /* start [s] */
    double start[2]; /* the command at t [m/s, rad/s] */
    double rate[2];  /* [m/s^2, rad/s^2]; 0: the start value is held */
    double stop[2];  /* a ramp holds here once it reaches it (+-inf: never) */
} PtProfilePiece;

typedef struct {
    int n_pieces;                 /* >= 1 */
    const PtProfilePiece *pieces; /* increasing t */
    double period;                /* > 0: the pieces repeat every period from t = 0; 0: once */
    int flip;                     /* PT_FLIP_* bits: channels negated in odd periods */
} PtProfile;

/* Size of PtProfile (which = 0) or PtProfilePiece (1) in bytes (a binding checks its layout). */
PT_API size_t pt_profile_sizeof(int which);

/* The profile's command at t [s] into cmd (v0 [m/s], w0 [rad/s]). Returns PT_OK, or
 * PT_ERR_ARGUMENT for a NULL pointer, no pieces or a negative or non-finite period. */
PT_API int pt_profile_command(const PtProfile *p, double t, double cmd[2]);

#ifdef __cplusplus
}
#endif

#endif /* PUSHTRAIN_OPENLOOP_H */
