/*
 * One communication step's closed-loop work (step.h). The push force and the errors are the
 * formulas of cosim/events.py's push_force and of the recorder's row, in the same order.
 */
#include "step.h"

#include <math.h>

size_t pt_step_sizeof(void) { return sizeof(PtStep); }

/* The push force and the errors of the true state truth against the reference sample. */
static void outputs(PtStep *s, const double *truth, const PtSample *sample) {
    const double th_n = truth[5];
    double dx, dy, c, sn;
    int i;
    s->push[0] = 0.0;
    s->push[1] = 0.0;
    for (i = 0; i < s->n_pushes; i++) {
        const double *p = s->pushes + 3 * i;
        s->push[0] += p[0] - sin(th_n) * p[2];
        s->push[1] += p[1] + cos(th_n) * p[2];
    }
    dx = truth[3] - sample->x; /* the last trailer's error in the reference frame */
    dy = truth[4] - sample->y;
    c = cos(sample->theta);
    sn = sin(sample->theta);
    s->errors[0] = c * dx + sn * dy;
    s->errors[1] = -sn * dx + c * dy;
    s->errors[2] = pt_wrap(th_n - sample->theta);
}

int pt_step(PtStep *s, double t, const double *truth, const double *noise, double *phi_meas) {
    PtTrack *track;
    const double *saved_phi;
    int status;
    if (s == NULL || s->track == NULL || s->sensors == NULL || truth == NULL ||
        phi_meas == NULL || (s->n_pushes > 0 && s->pushes == NULL)) {
        return PT_ERR_ARGUMENT;
    }
    track = s->track;
    saved_phi = track->m.phi;
    track->t = t;
    pt_measure(s->sensors, truth, noise, phi_meas, &track->m);
    track->m.phi = phi_meas;
    status = pt_track(track);
    track->m.phi = saved_phi;
    if (status != PT_OK) {
        return status;
    }
    outputs(s, truth, &track->sample);
    return PT_OK;
}
