/*
 * Open-loop command profiles (openloop.h), compiled with -ffp-contract=off like the engine:
 * each value is the formula of tests/reference/openloop.py in the same order, so both give the
 * same bits.
 */
#include "openloop.h"

#include <math.h>

size_t pt_profile_sizeof(int which) {
    return which == 0 ? sizeof(PtProfile) : which == 1 ? sizeof(PtProfilePiece) : 0;
}

/* A channel dt [s] into its piece: start + rate dt, held at stop once reached. */
static double ramp(double start, double rate, double stop, double dt) {
    double x;
    if (rate == 0.0) {
        return start;
    }
    x = start + rate * dt;
    if (rate > 0.0) {
        return x < stop ? x : stop;
    }
    return x > stop ? x : stop; /* Python's max(stop, x) */
}

int pt_profile_command(const PtProfile *p, double t, double cmd[2]) {
    const PtProfilePiece *piece = NULL;
    double tau = t;
    int odd = 0, i;
    if (p == NULL || cmd == NULL || p->pieces == NULL || p->n_pieces < 1 ||
        !(p->period >= 0.0 && p->period < INFINITY)) {
        return PT_ERR_ARGUMENT;
    }
    cmd[0] = 0.0;
    cmd[1] = 0.0;
    if (p->period > 0.0) {
        double k;
        if (t < 0.0) {
            return PT_OK;
        }
        /* k, tau = divmod(t, period) for t >= 0 (CPython's float_divmod) */
        tau = fmod(t, p->period);
        k = (t - tau) / p->period;
        if (k != 0.0) {
            const double f = floor(k);
            k = (k - f > 0.5) ? f + 1.0 : f;
        }
        odd = fmod(k, 2.0) != 0.0;
    }
    for (i = 0; i < p->n_pieces && p->pieces[i].t <= tau; i++) {
        piece = p->pieces + i;
    }
    if (piece == NULL) {
        return PT_OK;
    }
    for (i = 0; i < 2; i++) {
        double x = ramp(piece->start[i], piece->rate[i], piece->stop[i], tau - piece->t);
        if (odd && (p->flip & (1 << i))) {
            x = -1.0 * x;
        }
        cmd[i] = x;
    }
    return PT_OK;
}
