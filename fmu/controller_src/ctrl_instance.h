/*
 * The BackwardController behind the FMI glue of fmu/src (fmu_model.h: instance.c under fmi2.c,
 * the glue the plant is built on too): the instance's model data, the controller model
 * (ctrl_model.h) with its mission table (ctrl_table.h), read from the FMU's resources when the
 * instance is made.
 */
#ifndef PUSHTRAIN_CTRL_INSTANCE_H
#define PUSHTRAIN_CTRL_INSTANCE_H

#include "fmu_model.h"
#include "ctrl_model.h"

/* The mission is held through pointers (the table, the reference's phases): no FMU states. */
#define MODEL_CAN_GET_AND_SET_STATE 0

struct ModelData {
    CtrlModel model;
    CtrlTable table;
    /* communication points: start + k h while the master's points stay on the grid of its first
       step h (as a master computes them, never by summing floats; a phase of the reference that
       ends on a point is then sampled alike), else the last point plus its step */
    double start_time, step_size;
    long steps; /* points on the grid so far; -1: off the grid (variable steps) */
};

#endif
