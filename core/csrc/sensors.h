/*
 * The sensor model of pushtrain in C99, written once: what the controller sees of the chain.
 * The co-simulation master (core/sensors.py through ctypes, cosim/csrc/master_loop.c) and the
 * controller FMU (fmu/controller_src/ctrl_model.c) all measure through these functions.
 *
 * Joint i (potentiometer), in this order (Section 3.1 of the paper, plus play and resolution):
 *
 *     play_i   <- clip(play_i, phi_i - b/2, phi_i + b/2)    backlash (play operator, band b)
 *     reading  =  play_i + bias_i + noise_i
 *     measured =  q * round(reading / q)                     quantization if q > 0 (round half
 *                                                            to even, as numpy.round)
 *
 * play_i starts at the first true angle measured. Poses (localization): measured = true + noise.
 * The noise is drawn by the caller (numpy's generator, so a run is reproducible from a seed) and
 * passed in already scaled; this file only adds it. A NaN true angle gives a NaN reading (as
 * numpy.clip), which the control law then refuses.
 *
 * Self-contained (<math.h>, <string.h>), reentrant, no allocation: every array is the caller's.
 * Compiled with -ffp-contract=off, it gives the numbers of the numpy formulas above bit for bit
 * (tests/reference/sensors.py, tests/test_sensors.py).
 */
#ifndef PUSHTRAIN_SENSORS_H
#define PUSHTRAIN_SENSORS_H

#include "control.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Noise blocks of one measurement, in this order (each present only if its bit is set): joint
 * angles (n), robot position (2), robot heading (1), then, if the last trailer's pose is
 * measured, its position (2) and heading (1). */
enum {
    PT_NOISE_JOINTS = 1,
    PT_NOISE_POSITION = 2,
    PT_NOISE_HEADING = 4
};

/* The sensors of an n-trailer chain and their memory (the potentiometers' play). */
typedef struct {
    int n;                 /* joints, >= 1 */
    const double *bias;    /* n joint biases [rad] (the caller may change them between calls) */
    double half_backlash;  /* half the play band [rad]; 0: no play */
    double quantization;   /* joint resolution [rad]; 0: none */
    int noise;             /* PT_NOISE_* bits: the blocks a measurement's noise holds */
    int measure_last_pose; /* 1: the last trailer's pose is measured directly too */
    double *play;          /* n: the potentiometers' positions [rad] (needed if
                            * half_backlash > 0) */
    int has_play;          /* 0: the play starts at the next true angles */
} PtSensors;

/* Size of PtSensors in bytes (a binding checks its layout). */
PT_API size_t pt_sensors_sizeof(void);

/* Number of noise values one measurement uses (the blocks above). */
PT_API int pt_sensors_noise_count(const PtSensors *s);

/* The joint readings reading[0..n-1] [rad] of the true angles phi[0..n-1]; noise: the n joint
 * noise values or NULL (none). Advances the play. */
PT_API void pt_measure_joints(PtSensors *s, const double *phi, const double *noise,
                              double *reading);

/* One measurement of the true state truth = (x0, y0, theta0, x_n, y_n, theta_n, phi_1..phi_n)
 * (n + 6 values, the plant's order) with the noise blocks of s->noise (NULL if s->noise is 0):
 * the joint readings into phi_meas (n), the measured poses and has_last into *m (m->phi is left
 * to the caller). Returns the number of noise values used. */
PT_API int pt_measure(PtSensors *s, const double *truth, const double *noise, double *phi_meas,
                      PtMeasurement *m);

#ifdef __cplusplus
}
#endif

#endif /* PUSHTRAIN_SENSORS_H */
