/*
 * The mission table of the BackwardController FMU (resources/reference.txt, written by
 * pushtrain.fmu.controller.render_table): the last trailer's line/arc segments and, for every
 * pulling run, the robot's reference rows that pushtrain's pull guide computed.
 *
 * Text, one keyword per record, '#' starts a comment, numbers in C/Python float syntax (the
 * decimal point is '.', whatever the process locale):
 *
 *     pushtrain-reference 1
 *     start X Y THETA             the last trailer's start pose [m, m, rad]
 *     t0 T0                       time of the start pose [s]
 *     speed V                     default speed |v| [m/s]
 *     cusp_dwell D                rest at every direction change [s]
 *     segments K                  then K lines: line|arc LENGTH CURVATURE push|pull SPEED
 *                                 (SPEED 0: the default speed)
 *     leader_runs J               then J runs, each "run ROWS" and ROWS lines T X Y THETA V W
 *
 * Loaded once, at fmi2Instantiate; the step functions never allocate.
 */
#ifndef PUSHTRAIN_CTRL_TABLE_H
#define PUSHTRAIN_CTRL_TABLE_H

#include <stddef.h>

#include "control.h"

#define CTRL_TABLE_FORMAT 1
#define CTRL_MSG_LEN 512

typedef struct {
    double start[3];
    double t0, speed, cusp_dwell;
    int n_segments;
    PtSegment *segments;
    int n_runs;
    int *offset;                    /* n_runs + 1 row offsets */
    double *t, *x, *y, *theta, *v, *w; /* the leader rows of every run, concatenated */
} CtrlTable;

/* The local file path of `file` in the FMU's resource folder given as a URI (fmi2Instantiate's
 * fmuResourceLocation): file:/p, file:///p, file://localhost/p and file:////p (one or more
 * slashes) with percent-encoding (%20, %C3%A9, ...) decoded; a Windows drive (file:///C:/p)
 * loses its leading slash. Returns 0 and writes a message on failure. */
int ctrl_resource_path(const char *uri, const char *file, char *path, size_t len, char *msg,
                       size_t msg_len);

/* Reads and checks the table at `path` into `table` (allocated; free with ctrl_table_free).
 * Returns 0 and writes "path:line: what is wrong" on failure (the table is then empty). */
int ctrl_table_load(const char *path, CtrlTable *table, char *msg, size_t msg_len);

void ctrl_table_free(CtrlTable *table);

#endif
