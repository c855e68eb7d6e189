/*
 * The planner's lookups on a distance field: the signed distance at points (bilinear between
 * the grid's nodes), the last trailer's poses along line and arc segments, and whether its
 * outline keeps its clearance at those poses. Their readable twins:
 * tests/reference/field_lookup.py (the lookup), tests/reference/sweep.py (poses, clearance).
 *
 * The grid: ny x nx node values, row-major, node (i, j) at (x0 + j h, y0 + i h) [m]. Outside the
 * nodes' rectangle (and at NaN) the distance is -HUGE_VAL: blocked.
 *
 * Compiled without fused multiply-add; every formula is written in the order of its twin, so
 * the doubles are the same. C99, reentrant, no allocation; every array is the caller's.
 */
#ifndef PUSHTRAIN_FIELD_H
#define PUSHTRAIN_FIELD_H

#include "control.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Signed distance [m] at `count` points (x[q], y[q]) into out[q]: DistanceField.at. */
PT_API void pt_field_at(const double *values, long ny, long nx, double x0, double y0, double h,
                        long count, const double *x, const double *y, double *out);

/* Number of poses pt_sample_segments writes for these segments ((length, curvature,
 * direction) each, `segments` holding 3 n_segments doubles) at `spacing` [m]: 1 + the sum of
 * max(1, ceil(length / spacing)); -1 for a non-finite or negative length, or a spacing not > 0. */
PT_API long pt_sample_count(int n_segments, const double *segments, double spacing);

/* The poses (x, y, theta) [m, m, rad] along the segments from `pose`, every <= `spacing` [m]
 * (each segment in max(1, ceil(length / spacing)) equal steps, the pose itself first): into
 * out (3 x pt_sample_count doubles). Each running sum is a sequential sum of the same
 * increments as planner.connect.sample_reference's. Returns PT_OK or PT_ERR_ARGUMENT. */
PT_API int pt_sample_segments(const double pose[3], int n_segments, const double *segments,
                              double spacing, double *out);

/* Whether a body keeps its clearance at `count` poses (3 doubles each): every one of its m
 * points (u[p], v[p]) [m] in its own frame (u along theta) has a signed distance of at least
 * threshold[p] [m]. A pose whose own signed distance is not below `reach` [m] is passed without
 * looking at its points. Returns 1 (all clear) or 0. */
PT_API int pt_poses_clear(const double *values, long ny, long nx, double x0, double y0, double h,
                          long count, const double *poses, double reach, long m, const double *u,
                          const double *v, const double *threshold);

#ifdef __cplusplus
}
#endif

#endif
