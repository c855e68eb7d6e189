/*
 * The BackwardController model: its variables, the joint sensors (core/csrc/sensors.c), one
 * evaluation of the control law at a communication point and the memory carried from one point
 * to the next.
 *
 * Outputs at time t are a function of t, the inputs at t and the memory committed at the
 * previous point (the previous command for the rate limits, the backlash play, done). They are
 * evaluated lazily, at the first fmi2Get after the inputs or the time changed, so a master that
 * sets the plant's outputs at t and then reads the command gets exactly pushtrain's loop
 * (apply -> record -> step): the command at t from the measurement at t.
 *
 * fmi2DoStep commits the memory of the FIRST evaluation read at the current point (or evaluates
 * then, if nothing was read): that is the command a master forwards to the plant. A Jacobi
 * master (libcosim, ecos, fmpy's SSP) reads the outputs right after the step, before it hands
 * the controller the plant's new outputs (ecos then reads them once more); a Gauss-Seidel
 * master sets the inputs first and then reads. A master that reads the command before setting
 * the inputs but forwards a later read would leave the rate limits one command off.
 * No allocation after ctrl_model_init.
 */
#ifndef PUSHTRAIN_CTRL_MODEL_H
#define PUSHTRAIN_CTRL_MODEL_H

#include <stdbool.h>
#include <stddef.h>

#include "control.h"
#include "sensors.h"
#include "ctrl_table.h"
#include "ctrl_variables.h"

typedef struct {
    PtControlState state; /* the rate limits' memory */
    double play[CTRL_N];  /* the backlash play of every joint */
    int play_valid;       /* 0 before the first measurement */
    int done;
} CtrlMemory;

typedef struct {
    double r[CTRL_N_REALS];
    int i[CTRL_N_INTEGERS];
    int b[CTRL_N_BOOLEANS];
    double time;
    CtrlMemory memory;  /* committed at the previous communication point */
    CtrlMemory next;    /* after the evaluation at `time` */
    bool evaluated;     /* the outputs are those of the current inputs at `time` */
    bool have_next;     /* `next` holds the first evaluation read at `time` */
    /* the mission, built from the table once */
    const CtrlTable *table;
    PtPhase *phases;
    PtReference reference;
    PtLeader leader;
    double goal[3]; /* the reference's end pose, theta wrapped */
} CtrlModel;

/* Builds the reference from the table (allocates its phases) and sets the start values.
 * Returns 0 with a message for a table the reference refuses. */
int ctrl_model_init(CtrlModel *m, const CtrlTable *table, char *msg, size_t len);
void ctrl_model_free(CtrlModel *m);

/* Every variable back to its start value, the memory forgotten (keeps the mission). */
void ctrl_model_set_defaults(CtrlModel *m);

/* Every parameter within its range ("name = value: allowed lo to hi unit (reason)"). */
int ctrl_model_check_parameters(const CtrlModel *m, char *msg, size_t len);

/* The memory at the start time from the parameters (v_start, w_start, dt_start). */
void ctrl_model_start(CtrlModel *m);

/* Makes the outputs current (see above). Returns 0 with a message if the law refuses. */
int ctrl_model_evaluate(CtrlModel *m, char *msg, size_t len);

/* The step: commits the evaluation at the current time and moves to t_next. */
int ctrl_model_step(CtrlModel *m, double t_next, char *msg, size_t len);

#endif
