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

/* The total push force on the last trailer (heading th_n [rad]) into s->push. */
static void push_force(PtStep *s, double th_n) {
    int i;
    s->push[0] = 0.0;
    s->push[1] = 0.0;
    for (i = 0; i < s->n_pushes; i++) {
        const double *p = s->pushes + 3 * i;
        s->push[0] += p[0] - sin(th_n) * p[2];
        s->push[1] += p[1] + cos(th_n) * p[2];
    }
}

/* An open-loop profile's step: the readings, the profile's command, a rest sample and errors
 * without a value (PT_NO_VALUE), the push force. */
static int open_loop(PtStep *s, double t, const double *truth, const double *noise,
                     double *phi_meas) {
    PtMeasurement m;
    int status;
    pt_measure(s->sensors, truth, noise, phi_meas, &m);
    status = pt_profile_command(s->profile, t, s->cmd);
    if (status != PT_OK) {
        return status;
    }
    s->sample.x = PT_NO_VALUE;
    s->sample.y = PT_NO_VALUE;
    s->sample.theta = PT_NO_VALUE;
    s->sample.v = 0.0;
    s->sample.w = 0.0;
    s->sample.direction = PT_REST;
    push_force(s, truth[5]);
    s->errors[0] = PT_NO_VALUE;
    s->errors[1] = PT_NO_VALUE;
    s->errors[2] = PT_NO_VALUE;
    return PT_OK;
}

int pt_step(PtStep *s, double t, const double *truth, const double *noise, double *phi_meas) {
    PtTrack *track;
    const double *saved_phi;
    int status;
    if (s == NULL || (s->track == NULL) == (s->profile == NULL) || s->sensors == NULL ||
        truth == NULL || phi_meas == NULL || (s->n_pushes > 0 && s->pushes == NULL) ||
        (s->governor != NULL && (s->governor_work == NULL || s->profile != NULL))) {
        return PT_ERR_ARGUMENT;
    }
    if (s->profile != NULL) {
        return open_loop(s, t, truth, noise, phi_meas);
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
    s->cmd[0] = track->cmd[0];
    s->cmd[1] = track->cmd[1];
    s->sample = track->sample;
    push_force(s, truth[5]);
    pt_tracking_errors(&track->sample, truth[3], truth[4], truth[5], s->errors);
    return PT_OK;
}
