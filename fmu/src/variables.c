/*
 * Get and set TrailerTrain's variables by value reference, independent of the FMI version.
 *
 * The numbering, names, types and causalities come from variables.h, which the builder generates
 * from fmu/variables.py; this file only says where each variable lives in ModelData. The switches
 * over the generated enums have no default, so -Wswitch names any variable left out here.
 * Outputs are read as last computed: the caller makes them current first (model_needs_outputs).
 */
#include <math.h>
#include <stdio.h>

#include "model.h"
#include "variables.h"

typedef struct {
    const VarInfo *info;
    int block; /* 0 for scalars */
    int index; /* body index i of an array element; the scalar's vr for scalars */
} VarRef;

static bool decode(const ModelData *m, unsigned vr, VarRef *out) {
    const unsigned block = vr / VR_STRIDE, index = vr % VR_STRIDE;
    const VarInfo *info;
    if (block >= BLOCK_END) {
        return false;
    }
    info = (block == 0) ? (index < SCALAR_VR_END ? &scalar_info[index] : NULL) : &block_info[block];
    if (info == NULL || info->name == NULL) {
        return false;
    }
    if (block != 0
        && ((int)index < info->first || (int)index > m->n + info->last_offset)) {
        return false;
    }
    out->info = info;
    out->block = (int)block;
    out->index = (int)index;
    return true;
}

const char *model_variable_name(const ModelData *m, unsigned vr, char *buffer, size_t len) {
    VarRef r;
    if (!decode(m, vr, &r)) {
        snprintf(buffer, len, "(unknown value reference %u)", vr);
    } else if (r.block == 0) {
        snprintf(buffer, len, "%s", r.info->name);
    } else {
        snprintf(buffer, len, "%s[%d]", r.info->name, r.index);
    }
    return buffer;
}

bool model_needs_outputs(const ModelData *m, unsigned vr) {
    VarRef r;
    return decode(m, vr, &r)
           && (r.info->causality == var_output || r.info->causality == var_calculated_parameter);
}

/* ---------------------------------------------------------------- where each variable lives */

static double *real_scalar(ModelData *m, enum ScalarVr vr) {
    switch (vr) {
    case vr_v_cmd: return &m->v_cmd;
    case vr_w_cmd: return &m->w_cmd;
    case vr_push_x: return &m->push_x;
    case vr_push_y: return &m->push_y;
    case vr_g: return &m->g;
    case vr_robot_tau: return &m->robot_tau;
    case vr_robot_acc_max: return &m->robot_acc_max;
    case vr_robot_alpha_max: return &m->robot_alpha_max;
    case vr_phi_max: return &m->phi_max;
    case vr_x0_start: return &m->x0_start;
    case vr_y0_start: return &m->y0_start;
    case vr_v_start: return &m->v_start;
    case vr_w_start: return &m->w_start;
    case vr_max_substep: return &m->max_substep;
    case vr_slip_substep: return &m->slip_substep;
    case vr_slip_mode: case vr_n: case vr_jackknifed: break; /* not Real */
    }
    return NULL;
}

static double *real_element(ModelData *m, enum Block block, int i) {
    switch (block) {
    case blk_front: return &m->front[i];
    case blk_rear: return &m->rear[i];
    case blk_mass: return &m->mass[i];
    case blk_inertia: return &m->inertia[i];
    case blk_payload: return &m->payload[i];
    case blk_mu: return &m->mu[i];
    case blk_theta_start: return &m->theta_start[i];
    case blk_x: return &m->x[i];
    case blk_y: return &m->y[i];
    case blk_theta: return &m->q[IX_THETA + i];
    case blk_phi: return &m->phi[i];
    case blk_v: return &m->v[i];
    case blk_w: return &m->w[i];
    case blk_F_lat: return &m->F_lat[i];
    case blk_F_lat_max: return &m->F_lat_max[i];
    case blk_slide: return &m->slide[i];
    case blk_hitch_fx: return &m->hitch_fx[i];
    case blk_hitch_fy: return &m->hitch_fy[i];
    case blk_slide_speed: return &m->slide_speed[i];
    case blk_slipping: break; /* not Real */
    }
    return NULL;
}

static double *real_variable(ModelData *m, VarRef r) {
    return (r.block == 0) ? real_scalar(m, (enum ScalarVr)r.index)
                          : real_element(m, (enum Block)r.block, r.index);
}

static const char *const type_names[] = {"Real", "Integer", "Boolean"};

/* r is a known variable of type `type`; else writes why not into msg. */
static bool check_type(const ModelData *m, unsigned vr, VarType type, VarRef *r, char *msg,
                       size_t len) {
    char name[64];
    if (!decode(m, vr, r)) {
        snprintf(msg, len, "unknown value reference %u", vr);
        return false;
    }
    if (r->info->type != type) {
        snprintf(msg, len, "%s (value reference %u) is a%s %s, not a%s %s",
                 model_variable_name(m, vr, name, sizeof(name)), vr,
                 r->info->type == var_integer ? "n" : "", type_names[r->info->type],
                 type == var_integer ? "n" : "", type_names[type]);
        return false;
    }
    return true;
}

/* ---------------------------------------------------------------- get */

bool model_get_real(const ModelData *m, unsigned vr, double *value, char *msg, size_t len) {
    VarRef r;
    const double *p;
    if (!check_type(m, vr, var_real, &r, msg, len)) {
        return false;
    }
    p = real_variable((ModelData *)m, r); /* only read */
    if (p == NULL) { /* a Real in variables.py that has no place in ModelData */
        snprintf(msg, len, "%s has no storage in this build", r.info->name);
        return false;
    }
    *value = *p;
    return true;
}

/* the Integer variable r (a scalar) */
static bool integer_value(const ModelData *m, VarRef r, int *value) {
    switch ((enum ScalarVr)r.index) {
    case vr_n: *value = m->n; return true;
    case vr_slip_mode: *value = m->slip_mode; return true;
    default: return false;
    }
}

bool model_get_integer(const ModelData *m, unsigned vr, int *value, char *msg, size_t len) {
    VarRef r;
    if (!check_type(m, vr, var_integer, &r, msg, len)) {
        return false;
    }
    if (r.block != 0 || !integer_value(m, r, value)) {
        snprintf(msg, len, "%s has no storage in this build", r.info->name);
        return false;
    }
    return true;
}

bool model_get_boolean(const ModelData *m, unsigned vr, bool *value, char *msg, size_t len) {
    VarRef r;
    if (!check_type(m, vr, var_boolean, &r, msg, len)) {
        return false;
    }
    if (r.block == 0 && r.index == vr_jackknifed) {
        *value = m->jackknifed;
        return true;
    }
    if (r.block == blk_slipping) {
        *value = m->slipping[r.index];
        return true;
    }
    snprintf(msg, len, "%s has no storage in this build", r.info->name);
    return false;
}

/* ---------------------------------------------------------------- set */

/* Only inputs and parameters can be set, parameters only in the setup phase (before the end of
   initialization); r is a known variable. */
static bool settable(const ModelData *m, unsigned vr, VarRef r, bool setup, char *msg,
                     size_t len) {
    char name[64];
    model_variable_name(m, vr, name, sizeof(name));
    switch (r.info->causality) {
    case var_input:
        return true;
    case var_parameter:
        if (!setup) {
            snprintf(msg, len, "parameter %s is fixed: it can be set only in Instantiated or "
                     "Initialization Mode", name);
            return false;
        }
        return true;
    case var_output: case var_calculated_parameter: case var_local:
        break;
    }
    if (r.block == 0 && r.index == vr_n) {
        snprintf(msg, len, "n is a constant fixed by the build (n = %d); build another FMU for "
                 "another number of trailers", m->n);
    } else {
        snprintf(msg, len, "%s is an output or calculated parameter and cannot be set", name);
    }
    return false;
}

bool model_set_real(ModelData *m, unsigned vr, double value, bool setup, char *msg, size_t len) {
    VarRef r;
    double *p;
    char name[64];
    if (!check_type(m, vr, var_real, &r, msg, len) || !settable(m, vr, r, setup, msg, len)) {
        return false;
    }
    p = real_variable(m, r);
    if (p == NULL) {
        snprintf(msg, len, "%s has no storage in this build", r.info->name);
        return false;
    }
    if (r.info->causality == var_input) {
        if (!isfinite(value)) {
            snprintf(msg, len, "input %s = %g: must be finite",
                     model_variable_name(m, vr, name, sizeof(name)), value);
            return false;
        }
        if (r.block == blk_slide && value != 0.0 && m->slip_mode == 1 && !setup) {
            /* slip_mode is fixed now; before, the combination is checked when initialization
               ends (model_check_combinations), whatever order the importer sets them in */
            snprintf(msg, len, "input %s = %g: an imposed slide is the kinematic disturbance of "
                     "slip_mode 0; with slip_mode = 1 push the trailer with push_x, push_y instead",
                     model_variable_name(m, vr, name, sizeof(name)), value);
            return false;
        }
        m->outputs_valid = false; /* outputs depend directly on the inputs */
    }
    *p = value; /* parameters are checked in model_check_parameters */
    return true;
}

bool model_set_integer(ModelData *m, unsigned vr, int value, bool setup, char *msg, size_t len) {
    VarRef r;
    if (!check_type(m, vr, var_integer, &r, msg, len) || !settable(m, vr, r, setup, msg, len)) {
        return false;
    }
    if (r.block == 0 && r.index == vr_slip_mode) {
        m->slip_mode = value; /* checked in model_check_parameters */
        return true;
    }
    snprintf(msg, len, "%s has no storage in this build", r.info->name);
    return false;
}

bool model_set_boolean(ModelData *m, unsigned vr, bool value, bool setup, char *msg,
                       size_t len) {
    VarRef r;
    (void)m;
    (void)value;
    if (!check_type(m, vr, var_boolean, &r, msg, len) || !settable(m, vr, r, setup, msg, len)) {
        return false;
    }
    snprintf(msg, len, "%s has no storage in this build", r.info->name);
    return false;
}

/* ---------------------------------------------------------------- parameter checks */

/* value of parameter r (Real or Integer) as a double; NaN if it has no storage */
static double parameter_value(const ModelData *m, VarRef r) {
    const double *p;
    int value;
    if (r.info->type == var_integer) {
        return (r.block == 0 && integer_value(m, r, &value)) ? (double)value : NAN;
    }
    p = real_variable((ModelData *)m, r); /* only read */
    return p != NULL ? *p : NAN;
}

static bool check_parameter(const ModelData *m, VarRef r, char *msg, size_t len) {
    const VarInfo *info = r.info;
    const double value = parameter_value(m, r);
    char name[64];
    if (info->bounded ? (value >= info->min && value <= info->max) : isfinite(value)) {
        return true;
    }
    if (r.block == 0) {
        snprintf(name, sizeof(name), "%s", info->name);
    } else {
        snprintf(name, sizeof(name), "%s[%d]", info->name, r.index);
    }
    if (info->bounded) {
        snprintf(msg, len, "%s = %g: allowed %g to %g%s%s (%s)", name, value, info->min,
                 info->max, info->unit[0] ? " " : "", info->unit, info->reason);
    } else {
        snprintf(msg, len, "%s = %g: must be finite", name, value);
    }
    return false;
}

bool model_check_parameters(const ModelData *m, char *msg, size_t len) {
    VarRef r;
    int block;
    for (r.index = 1; r.index < SCALAR_VR_END; r.index++) {
        r.block = 0;
        r.info = &scalar_info[r.index];
        if (r.info->name != NULL && r.info->causality == var_parameter
            && !check_parameter(m, r, msg, len)) {
            return false;
        }
    }
    for (block = 1; block < BLOCK_END; block++) {
        r.block = block;
        r.info = &block_info[block];
        if (r.info->name == NULL || r.info->causality != var_parameter) {
            continue;
        }
        for (r.index = r.info->first; r.index <= m->n + r.info->last_offset; r.index++) {
            if (!check_parameter(m, r, msg, len)) {
                return false;
            }
        }
    }
    return true;
}
