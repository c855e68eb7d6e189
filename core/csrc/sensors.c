/*
 * The sensor model (sensors.h): every formula is the numpy one of tests/reference/sensors.py in
 * the same order.
 */
#include "sensors.h"

#include <math.h>
#include <string.h>

size_t pt_sensors_sizeof(void) { return sizeof(PtSensors); }

int pt_sensors_noise_count(const PtSensors *s) {
    const int pose = ((s->noise & PT_NOISE_POSITION) ? 2 : 0) +
                     ((s->noise & PT_NOISE_HEADING) ? 1 : 0);
    return ((s->noise & PT_NOISE_JOINTS) ? s->n : 0) + pose * (s->measure_last_pose ? 2 : 1);
}

/* np.clip(p, lo, hi): a NaN bound gives NaN, as numpy.maximum / numpy.minimum do. */
static double clip(double p, double lo, double hi) {
    p = (p < lo || lo != lo) ? lo : p;
    return (p > hi || hi != hi) ? hi : p;
}

void pt_measure_joints(PtSensors *s, const double *phi, const double *noise, double *reading) {
    const int n = s->n;
    const double half = s->half_backlash, q = s->quantization;
    int i;
    if (half == 0.0) { /* no play: the potentiometer follows the joint */
        for (i = 0; i < n; i++) {
            reading[i] = phi[i] + s->bias[i];
        }
    } else {
        if (!s->has_play) {
            memcpy(s->play, phi, (size_t)n * sizeof(double));
            s->has_play = 1;
        } else {
            for (i = 0; i < n; i++) {
                s->play[i] = clip(s->play[i], phi[i] - half, phi[i] + half);
            }
        }
        for (i = 0; i < n; i++) {
            reading[i] = s->play[i] + s->bias[i];
        }
    }
    if (noise != NULL) {
        for (i = 0; i < n; i++) {
            reading[i] += noise[i];
        }
    }
    if (q > 0.0) {
        for (i = 0; i < n; i++) { /* q * np.round(reading / q): round half to even */
            reading[i] = q * rint(reading[i] / q);
        }
    }
}

/* One pose reading: the noise blocks of s->noise added from noise[*used] on. */
static void measure_pose(const PtSensors *s, double *x, double *y, double *theta,
                         const double *noise, int *used) {
    if (s->noise & PT_NOISE_POSITION) {
        *x = *x + noise[*used];
        *y = *y + noise[*used + 1];
        *used += 2;
    }
    if (s->noise & PT_NOISE_HEADING) {
        *theta = *theta + noise[*used];
        *used += 1;
    }
}

int pt_measure(PtSensors *s, const double *truth, const double *noise, double *phi_meas,
               PtMeasurement *m) {
    int used = 0;
    pt_measure_joints(s, truth + 6, (s->noise & PT_NOISE_JOINTS) ? noise : NULL, phi_meas);
    if (s->noise & PT_NOISE_JOINTS) {
        used = s->n;
    }
    m->x0 = truth[0], m->y0 = truth[1], m->theta0 = truth[2];
    measure_pose(s, &m->x0, &m->y0, &m->theta0, noise, &used);
    m->has_last = s->measure_last_pose;
    if (s->measure_last_pose) {
        m->x_n = truth[3], m->y_n = truth[4], m->theta_n = truth[5];
        measure_pose(s, &m->x_n, &m->y_n, &m->theta_n, noise, &used);
    }
    return used;
}
