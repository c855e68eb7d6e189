/*
 * One communication step's closed-loop work (step.h). The push force and the errors are the
 * formulas of cosim/events.py's push_force and of the recorder's row, in the same order.
 */
#include "step.h"

#include <math.h>

size_t pt_step_sizeof(void) { return sizeof(PtStep); }

void pt_tracking_errors(const PtSample *sample, double x, double y, double theta,
                        double errors[3]) {
    const double dx = x - sample->x, dy = y - sample->y;
    const double c = cos(sample->theta), sn = sin(sample->theta);
    errors[0] = c * dx + sn * dy;
    errors[1] = -sn * dx + c * dy;
    errors[2] = pt_wrap(theta - sample->theta);
}

/* The push force and the errors of the true state truth against the reference sample. */
static void outputs(PtStep *s, const double *truth, const PtSample *sample) {
    const double th_n = truth[5];
    int i;
    s->push[0] = 0.0;
    s->push[1] = 0.0;
    for (i = 0; i < s->n_pushes; i++) {
        const double *p = s->pushes + 3 * i;
        s->push[0] += p[0] - sin(th_n) * p[2];
        s->push[1] += p[1] + cos(th_n) * p[2];
    }
    pt_tracking_errors(sample, truth[3], truth[4], th_n, s->errors);
}

int pt_step(PtStep *s, double t, const double *truth, const double *noise, double *phi_meas) {
    PtTrack *track;
    const double *saved_phi;
    int status;
    if (s == NULL || s->track == NULL || s->sensors == NULL || truth == NULL ||
        phi_meas == NULL || (s->n_pushes > 0 && s->pushes == NULL) ||
        (s->governor != NULL && s->governor_work == NULL)) {
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
    if (s->governor != NULL) { /* governor.GovernedController.command */
        double v = track->cmd[0], w = track->cmd[1];
        pt_governor_limit(s->governor, phi_meas, &v, &w, s->governor_work);
        if (v != track->cmd[0] || w != track->cmd[1]) {
            pt_control_sent(track->state, v, w); /* the rate limits go on from what is sent */
            track->cmd[0] = v;
            track->cmd[1] = w;
        }
    }
    outputs(s, truth, &track->sample);
    return PT_OK;
}
