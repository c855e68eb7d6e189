/*
 * The backward-motion control law (see control.h). Each function names the Python function it
 * mirrors; expressions keep Python's order of evaluation so that both round alike.
 */
#include <math.h>
#include <stddef.h>
#include <string.h>

#include "control.h"
#include "ode.h"

#define PT_PI 3.141592653589793115997963468544185161590576171875

/* Python's max(a, b) and min(a, b) on floats: the first argument unless the second compares
 * strictly greater (smaller); NaN therefore behaves as in Python. */
static double py_max(double a, double b) { return (b > a) ? b : a; }
static double py_min(double a, double b) { return (b < a) ? b : a; }

/* Python's float modulo a % m: the result takes the sign of m. */
static double py_mod(double a, double m) {
    double r = fmod(a, m);
    if (r != 0.0) {
        if ((m < 0.0) != (r < 0.0)) {
            r += m;
        }
    } else {
        r = copysign(0.0, m);
    }
    return r;
}

/* bisect.bisect_right(a[0..len-1], x). */
static int bisect_right(const double *a, int len, double x) {
    int lo = 0, hi = len;
    while (lo < hi) {
        int mid = (lo + hi) / 2;
        if (x < a[mid]) {
            hi = mid;
        } else {
            lo = mid + 1;
        }
    }
    return lo;
}

static int is_finite(double a) { return isfinite(a) ? 1 : 0; }

size_t pt_sizeof(int which) {
    switch (which) {
    case 0: return sizeof(PtChain);
    case 1: return sizeof(PtSample);
    case 2: return sizeof(PtController);
    case 3: return sizeof(PtControlState);
    case 4: return sizeof(PtMeasurement);
    case 5: return sizeof(PtControlInfo);
    case 6: return sizeof(PtSegment);
    case 7: return sizeof(PtPhase);
    case 8: return sizeof(PtReference);
    case 9: return sizeof(PtLeader);
    case 10: return sizeof(PtTrack);
    default: return 0;
    }
}

/* ------------------------------------------------------------------ kinematics */

double pt_wrap(double angle) {
    const double wrapped = py_mod(angle + PT_PI, 2.0 * PT_PI) - PT_PI;
    return (wrapped == -PT_PI) ? PT_PI : wrapped;
}

void pt_chain_positions(const PtChain *chain, const double *cs, const double *sn, double x_a,
                        double y_a, int from_last, double *x, double *y) {
    const int n = chain->n;
    double dx = 0.0, dy = 0.0;
    int i;
    if (from_last) {
        x[n] = x_a;
        y[n] = y_a;
        for (i = n - 1; i >= 0; i--) {
            dx += chain->front[i] * cs[i + 1] + chain->rear[i] * cs[i];
            dy += chain->front[i] * sn[i + 1] + chain->rear[i] * sn[i];
            x[i] = x_a + dx;
            y[i] = y_a + dy;
        }
        return;
    }
    x[0] = x_a;
    y[0] = y_a;
    for (i = 1; i <= n; i++) {
        dx -= chain->rear[i - 1] * cs[i - 1] + chain->front[i - 1] * cs[i];
        dy -= chain->rear[i - 1] * sn[i - 1] + chain->front[i - 1] * sn[i];
        x[i] = x_a + dx;
        y[i] = y_a + dy;
    }
}

void pt_body_positions(const PtChain *chain, long rows, const double *theta, const double *x_a,
                       const double *y_a, int from_last, double *x, double *y, double *work) {
    const int nb = chain->n + 1;
    double *cs = work, *sn = work + nb;
    long r;
    int i;
    for (r = 0; r < rows; r++) {
        for (i = 0; i < nb; i++) {
            cs[i] = cos(theta[r * nb + i]);
            sn[i] = sin(theta[r * nb + i]);
        }
        pt_chain_positions(chain, cs, sn, x_a[r], y_a[r], from_last, x + r * nb, y + r * nb);
    }
}

void pt_last_trailer_pose(const PtChain *chain, double x0, double y0, double theta0,
                          const double *phi, double pose[3]) {
    const int n = chain->n;
    double cs[n + 1], sn[n + 1], x[n + 1], y[n + 1];
    double th = theta0;
    int i;
    cs[0] = cos(th);
    sn[0] = sin(th);
    for (i = 0; i < n; i++) {
        th -= phi[i];
        cs[i + 1] = cos(th);
        sn[i + 1] = sin(th);
    }
    pt_chain_positions(chain, cs, sn, x0, y0, 0, x, y);
    pose[0] = x[n];
    pose[1] = y[n];
    pose[2] = th;
}

void pt_robot_velocity_from_last(const PtChain *chain, const double *phi, double v_n, double w_n,
                                 double out[2]) {
    double v = v_n, w = w_n;
    int i;
    for (i = chain->n - 1; i >= 0; i--) {
        const double c = cos(phi[i]), s = sin(phi[i]);
        const double f = chain->front[i];
        const double v_new = c * v + f * s * w;
        w = (s * v - f * c * w) / chain->rear[i];
        v = v_new;
    }
    out[0] = v;
    out[1] = w;
}

void pt_rates_from_last(const PtChain *chain, const double *theta, double v_n, double w_n,
                        double *w) {
    const int n = chain->n;
    double v = v_n;
    int i;
    w[n] = w_n;
    for (i = n - 1; i >= 0; i--) {
        const double phi = theta[i] - theta[i + 1];
        const double c = cos(phi), s = sin(phi);
        const double f = chain->front[i];
        const double v_new = c * v + f * s * w[i + 1];
        w[i] = (s * v - f * c * w[i + 1]) / chain->rear[i];
        v = v_new;
    }
}

void pt_towed_rates(const PtChain *chain, const double *theta, double v0, double w0, double *w) {
    double v = v0;
    int i;
    w[0] = w0;
    for (i = 1; i <= chain->n; i++) {
        const double phi = theta[i - 1] - theta[i];
        const double c = cos(phi), s = sin(phi);
        const double r = chain->rear[i - 1];
        const double v_new = c * v + r * s * w[i - 1];
        w[i] = (s * v - r * c * w[i - 1]) / chain->front[i - 1];
        v = v_new;
    }
}

/* ------------------------------------------------------------------ the control law */

void pt_kanayama(const PtController *c, double x_e, double y_e, double th_e, double u_d,
                 double w_d, double out[2]) {
    out[0] = u_d * cos(th_e) + c->k_x * x_e;
    out[1] = w_d + u_d * (c->k_y * y_e + c->k_theta * sin(th_e));
}

void pt_control_reset(PtControlState *state, double v0, double w0, double t, int has_t) {
    state->v_prev = v0;
    state->w_prev = w0;
    state->t_prev = has_t ? t : 0.0;
    state->has_t_prev = has_t ? 1 : 0;
}

void pt_control_sent(PtControlState *state, double v0, double w0) {
    state->v_prev = v0;
    state->w_prev = w0;
}

/* Kanayama on the last trailer in its direction-of-travel frame (BackwardController._push). */
static void push_law(const PtController *c, const PtSample *ref, const double pose[3],
                     PtControlInfo *info) {
    const double dx = ref->x - pose[0], dy = ref->y - pose[1];
    const double cs = cos(pose[2]), sn = sin(pose[2]);
    double uw[2];
    info->x_e = -(cs * dx + sn * dy);
    info->y_e = sn * dx - cs * dy;
    info->theta_e = pt_wrap(ref->theta - pose[2]);
    pt_kanayama(c, info->x_e, info->y_e, info->theta_e, -ref->v, ref->w, uw);
    info->v_ref = uw[0];
    info->w_ref = uw[1];
}

/* Kanayama on the robot in its forward frame along its own reference (BackwardController._pull). */
static void pull_law(const PtController *c, const PtSample *leader, const PtMeasurement *m,
                     PtControlInfo *info) {
    const double dx = leader->x - m->x0, dy = leader->y - m->y0;
    const double cs = cos(m->theta0), sn = sin(m->theta0);
    double uw[2];
    info->x_e = cs * dx + sn * dy;
    info->y_e = -sn * dx + cs * dy;
    info->theta_e = pt_wrap(leader->theta - m->theta0);
    pt_kanayama(c, info->x_e, info->y_e, info->theta_e, fabs(leader->v), leader->w, uw);
    info->v_ref = uw[0];
    info->w_ref = uw[1];
}

/* The common-factor speed limit and the optional rate limits (BackwardController._limit). */
static int limit(const PtController *c, PtControlState *state, double t, PtControlInfo *info,
                 double cmd[2]) {
    double v = info->v_raw, w = info->w_raw, scale = 1.0;
    if (!is_finite(v) || !is_finite(w)) {
        return PT_ERR_NONFINITE_COMMAND;
    }
    scale = py_max(scale, fabs(v) / c->v_max);
    scale = py_max(scale, fabs(w) / c->w_max);
    if (!is_finite(scale)) {
        return PT_ERR_NONFINITE_COMMAND;
    }
    v /= scale;
    w /= scale;
    if ((c->acc_max > 0.0 || c->alpha_max > 0.0) && state->has_t_prev && t > state->t_prev) {
        const double dt = t - state->t_prev;
        const double dv = v - state->v_prev, dw = w - state->w_prev;
        double r = 1.0;
        if (c->acc_max > 0.0) {
            r = py_max(r, fabs(dv) / (c->acc_max * dt));
        }
        if (c->alpha_max > 0.0) {
            r = py_max(r, fabs(dw) / (c->alpha_max * dt));
        }
        v = state->v_prev + dv / r;
        w = state->w_prev + dw / r;
    }
    state->v_prev = v;
    state->w_prev = w;
    state->t_prev = t;
    state->has_t_prev = 1;
    info->scale = scale;
    cmd[0] = v;
    cmd[1] = w;
    return PT_OK;
}

int pt_command(const PtController *c, PtControlState *state, double t, const PtMeasurement *m,
               const PtSample *ref, const PtSample *leader, double cmd[2], PtControlInfo *info) {
    PtControlInfo local;
    double pose[3];
    int i, n;
    if (c == NULL || state == NULL || m == NULL || ref == NULL || cmd == NULL ||
        c->model.n < 1 || (m->phi == NULL && c->model.n > 0)) {
        return PT_ERR_ARGUMENT;
    }
    if (info == NULL) {
        info = &local;
    }
    memset(info, 0, sizeof(*info));
    n = c->model.n;
    if (!is_finite(m->x0) || !is_finite(m->y0) || !is_finite(m->theta0)) {
        return PT_ERR_NONFINITE_MEASUREMENT;
    }
    for (i = 0; i < n; i++) {
        if (!is_finite(m->phi[i])) {
            return PT_ERR_NONFINITE_MEASUREMENT;
        }
    }
    if (m->has_last) {
        pose[0] = m->x_n;
        pose[1] = m->y_n;
        pose[2] = m->theta_n;
    } else {
        pt_last_trailer_pose(&c->model, m->x0, m->y0, m->theta0, m->phi, pose);
    }
    if (!is_finite(pose[0]) || !is_finite(pose[1]) || !is_finite(pose[2])) {
        return PT_ERR_NONFINITE_MEASUREMENT;
    }
    info->x_n = pose[0];
    info->y_n = pose[1];
    info->theta_n = pose[2];
    if (ref->direction == PT_REST || fabs(ref->v) <= c->rest_speed) {
        info->mode = PT_MODE_REST;
    } else if (ref->direction == PT_PUSH) {
        double vw[2];
        info->mode = PT_MODE_PUSH;
        push_law(c, ref, pose, info);
        pt_robot_velocity_from_last(&c->model, m->phi, -info->v_ref, info->w_ref, vw); /* Eq. 5 */
        info->v_raw = vw[0];
        info->w_raw = vw[1];
    } else if (ref->direction == PT_PULL) {
        if (leader == NULL) {
            return PT_ERR_NO_LEADER;
        }
        info->mode = PT_MODE_PULL;
        pull_law(c, leader, m, info);
        info->v_raw = info->v_ref;
        info->w_raw = info->w_ref;
    } else {
        return PT_ERR_DIRECTION;
    }
    return limit(c, state, t, info, cmd);
}

/* ------------------------------------------------------------------ the reference */

/* Pose after travelling s [m] along a line or arc (Eq. 1 integrated in closed form). */
static void advance(double x, double y, double theta, double sigma, double kappa, double s,
                    double out[3]) {
    const double th = theta + kappa * s;
    if (fabs(kappa) < 1e-12) {
        out[0] = x + sigma * s * cos(theta);
        out[1] = y + sigma * s * sin(theta);
    } else {
        out[0] = x + sigma * (sin(th) - sin(theta)) / kappa;
        out[1] = y - sigma * (cos(th) - cos(theta)) / kappa;
    }
    out[2] = th;
}

int pt_reference_init(PtReference *r, PtPhase *storage, int capacity, const double start[3],
                      double speed, double cusp_dwell, double t0, int previous_direction) {
    if (r == NULL || start == NULL || capacity < 0 || (storage == NULL && capacity > 0)) {
        return PT_ERR_ARGUMENT;
    }
    if (!is_finite(start[0]) || !is_finite(start[1]) || !is_finite(start[2]) ||
        !(is_finite(speed) && speed > 0.0) || !(is_finite(cusp_dwell) && cusp_dwell >= 0.0) ||
        !is_finite(t0) || previous_direction < -1 || previous_direction > 1) {
        return PT_ERR_ARGUMENT;
    }
    r->phases = storage;
    r->capacity = capacity;
    r->n_phases = 0;
    r->t0 = t0;
    r->speed = speed;
    r->cusp_dwell = cusp_dwell;
    r->t_end = t0;
    r->x_end = start[0];
    r->y_end = start[1];
    r->theta_end = start[2];
    r->last_direction = previous_direction;
    return PT_OK;
}

static void set_phase(PtPhase *p, double t, double x, double y, double theta, double sigma,
                      double kappa, double speed) {
    p->t = t;
    p->x = x;
    p->y = y;
    p->theta = theta;
    p->sigma = sigma;
    p->kappa = kappa;
    p->speed = speed;
}

int pt_reference_append(PtReference *r, const PtSegment *seg) {
    int dwell;
    double speed, sigma, pose[3];
    if (r == NULL || seg == NULL) {
        return PT_ERR_ARGUMENT;
    }
    /* Segment.__post_init__ */
    if ((seg->kind != PT_LINE && seg->kind != PT_ARC) ||
        !(is_finite(seg->length) && seg->length > 0.0) || !is_finite(seg->curvature) ||
        (seg->kind == PT_LINE && seg->curvature != 0.0) ||
        (seg->kind == PT_ARC && seg->curvature == 0.0) ||
        (seg->direction != PT_PUSH && seg->direction != PT_PULL) ||
        !(is_finite(seg->speed) && seg->speed >= 0.0)) {
        return PT_ERR_SEGMENT;
    }
    dwell = (r->last_direction != 0 && seg->direction != r->last_direction &&
             r->cusp_dwell > 0.0);
    if (r->n_phases + 1 + dwell > r->capacity) {
        return PT_ERR_CAPACITY;
    }
    if (dwell) {
        set_phase(&r->phases[r->n_phases++], r->t_end, r->x_end, r->y_end, r->theta_end, 0.0,
                  0.0, 0.0);
        r->t_end += r->cusp_dwell;
    }
    speed = (seg->speed == 0.0) ? r->speed : seg->speed;
    sigma = -(double)seg->direction;
    set_phase(&r->phases[r->n_phases++], r->t_end, r->x_end, r->y_end, r->theta_end, sigma,
              seg->curvature, speed);
    advance(r->x_end, r->y_end, r->theta_end, sigma, seg->curvature, seg->length, pose);
    r->x_end = pose[0];
    r->y_end = pose[1];
    r->theta_end = pose[2];
    r->t_end += seg->length / speed;
    r->last_direction = seg->direction;
    return PT_OK;
}

/* bisect_right over the phases' start times. */
static int phase_bisect_right(const PtReference *r, double x) {
    int lo = 0, hi = r->n_phases;
    while (lo < hi) {
        int mid = (lo + hi) / 2;
        if (x < r->phases[mid].t) {
            hi = mid;
        } else {
            lo = mid + 1;
        }
    }
    return lo;
}

int pt_reference_sample(const PtReference *r, double t, PtSample *out) {
    double tc, pose[3];
    int k;
    const PtPhase *p;
    if (r == NULL || out == NULL) {
        return PT_ERR_ARGUMENT;
    }
    if (r->n_phases < 1) {
        return PT_ERR_EMPTY_REFERENCE;
    }
    tc = py_min(py_max(t, r->t0), r->t_end);
    k = phase_bisect_right(r, tc) - 1;
    if (k < 0) {
        k = 0;
    }
    if (k > r->n_phases - 1) {
        k = r->n_phases - 1;
    }
    p = &r->phases[k];
    advance(p->x, p->y, p->theta, p->sigma, p->kappa, p->speed * (tc - p->t), pose);
    out->x = pose[0];
    out->y = pose[1];
    out->theta = pose[2];
    if (r->t0 <= t && t < r->t_end && p->sigma != 0.0) {
        out->v = p->sigma * p->speed;
        out->w = p->kappa * p->speed;
        out->direction = (int)(-p->sigma);
    } else {
        out->v = 0.0;
        out->w = 0.0;
        out->direction = PT_REST;
    }
    return PT_OK;
}

int pt_reference_samples(const PtReference *r, const double *t, int count, double *x,
                         double *y, double *theta, double *v, double *w, int *direction) {
    int i;
    if (t == NULL || count < 0 || (count > 0 && (x == NULL || y == NULL || theta == NULL ||
                                                 v == NULL || w == NULL || direction == NULL))) {
        return PT_ERR_ARGUMENT;
    }
    for (i = 0; i < count; i++) {
        PtSample s;
        const int status = pt_reference_sample(r, t[i], &s);
        if (status != PT_OK) {
            return status;
        }
        x[i] = s.x;
        y[i] = s.y;
        theta[i] = s.theta;
        v[i] = s.v;
        w[i] = s.w;
        direction[i] = s.direction;
    }
    return PT_OK;
}

int pt_reference_pull_intervals(const PtReference *r, double *t_a, double *t_b, int capacity) {
    int k = 0, count = 0;
    if (r == NULL || capacity < 0 || (capacity > 0 && (t_a == NULL || t_b == NULL))) {
        return -PT_ERR_ARGUMENT;
    }
    while (k < r->n_phases) {
        int j;
        if (r->phases[k].sigma != 1.0) { /* sigma = -direction: +1 pulls */
            k++;
            continue;
        }
        j = k;
        while (j < r->n_phases && r->phases[j].sigma == 1.0) {
            j++;
        }
        {
            const double a = r->phases[k].t;
            const double b = (j < r->n_phases) ? r->phases[j].t : r->t_end;
            if (b > a) {
                if (count < capacity) {
                    t_a[count] = a;
                    t_b[count] = b;
                }
                count++;
            }
        }
        k = j;
    }
    return count;
}

/* ------------------------------------------------------------------ the pull guide */

int pt_pull_run_rows(double t_a, double t_b, double step) {
    double steps;
    if (!(is_finite(t_a) && is_finite(t_b) && t_b > t_a && is_finite(step) && step > 0.0)) {
        return -PT_ERR_ARGUMENT;
    }
    steps = ceil((t_b - t_a) / step);
    if (!(steps < 1e8)) {
        return -PT_ERR_ARGUMENT;
    }
    return (steps < 1.0 ? 1 : (int)steps) + 1;
}

int pt_pull_run_work(int n) { return 6 * (n + 1); }

/* A reference and its sampling function. */
typedef struct {
    PtSampler sample;
    const void *source;
} Sampled;

/* The reference at t clamped to [t_a, t_b - eps] (the backward run's vw and last). */
static void clamped_sample(const Sampled *ref, double t, double t_a, double t_end_eps,
                           PtSample *s) {
    ref->sample(ref->source, py_min(py_max(t, t_a), t_end_eps), s);
}

/* Times of the backward run: numpy.linspace(t_b, t_a, k_steps + 1)[j]. */
static double run_time(double t_b, double t_a, int k_steps, int j) {
    const double delta = t_a - t_b;
    const double dstep = delta / (double)k_steps;
    if (j == k_steps) {
        return t_a;
    }
    if (dstep == 0.0) {
        return (double)j / (double)k_steps * delta + t_b;
    }
    return (double)j * dstep + t_b;
}

/* One output row of the run at time tau with headings theta: the robot's position from the
 * last trailer's (pt_chain_positions), its velocity through pt_robot_velocity_from_last. */
static void pull_row(const PtChain *model, const Sampled *ref, double tau, double t_a,
                     double t_end_eps, const double *theta, double *phi, int row, double *T,
                     double *X, double *Y, double *TH, double *V, double *W, double *headings) {
    const int n = model->n;
    PtSample s;
    double cs[n + 1], sn[n + 1], bx[n + 1], by[n + 1], vw[2];
    int k;
    clamped_sample(ref, tau, t_a, t_end_eps, &s);
    for (k = 0; k <= n; k++) {
        cs[k] = cos(theta[k]);
        sn[k] = sin(theta[k]);
    }
    pt_chain_positions(model, cs, sn, s.x, s.y, 1, bx, by); /* the robot's position from the last */
    for (k = 0; k < n; k++) {
        phi[k] = theta[k] - theta[k + 1];
    }
    pt_robot_velocity_from_last(model, phi, s.v, s.w, vw);
    T[row] = tau;
    X[row] = bx[0];
    Y[row] = by[0];
    TH[row] = theta[0];
    V[row] = vw[0];
    W[row] = vw[1];
    if (headings != NULL) {
        memcpy(headings + (size_t)row * (size_t)(n + 1), theta, sizeof(double) * (size_t)(n + 1));
    }
}

/* The backward run's ODE: d(theta)/dt driven by the last trailer's reference at time t. */
typedef struct {
    const PtChain *model;
    const Sampled *ref;
    double t_a, t_end_eps;
} Driven;

static inline void driven(const void *context, double t, const double *theta, double *rates) {
    const Driven *d = (const Driven *)context;
    PtSample s;
    clamped_sample(d->ref, t, d->t_a, d->t_end_eps, &s);
    pt_rates_from_last(d->model, theta, s.v, s.w, rates);
}

static int reference_sampler(const void *source, double t, PtSample *out) {
    return pt_reference_sample((const PtReference *)source, t, out);
}

int pt_pull_run(const PtChain *model, const PtReference *ref, double t_a, double t_b, double step,
                double *work, double *T, double *X, double *Y, double *TH, double *V, double *W,
                double *headings) {
    if (ref == NULL) {
        return PT_ERR_ARGUMENT;
    }
    if (ref->n_phases < 1) {
        return PT_ERR_EMPTY_REFERENCE;
    }
    return pt_pull_run_sampled(model, reference_sampler, ref, t_a, t_b, step, work, T, X, Y, TH,
                               V, W, headings);
}

int pt_pull_run_sampled(const PtChain *model, PtSampler sample, const void *source, double t_a,
                        double t_b, double step, double *work, double *T, double *X, double *Y,
                        double *TH, double *V, double *W, double *headings) {
    int rows, k_steps, k, i, nb;
    double eps, t_end_eps;
    double *theta, *tmp;
    PtSample end;
    Sampled ref;
    Driven rates;
    if (model == NULL || sample == NULL || work == NULL || T == NULL || X == NULL || Y == NULL ||
        TH == NULL || V == NULL || W == NULL || model->n < 1) {
        return PT_ERR_ARGUMENT;
    }
    rows = pt_pull_run_rows(t_a, t_b, step);
    if (rows < 0) {
        return PT_ERR_ARGUMENT;
    }
    ref.sample = sample;
    ref.source = source;
    k_steps = rows - 1;
    nb = model->n + 1;
    theta = work;
    tmp = work + 5 * nb; /* holds phi (n values) in pull_row; work + nb.. is the RK4's */
    eps = 1e-9 * py_max(1.0, fabs(t_b));
    t_end_eps = t_b - eps;
    rates.model = model;
    rates.ref = &ref;
    rates.t_a = t_a;
    rates.t_end_eps = t_end_eps;
    sample(source, t_end_eps, &end);
    for (i = 0; i < nb; i++) {
        theta[i] = end.theta; /* drawn out straight at the run's end */
    }
    pull_row(model, &ref, t_b, t_a, t_end_eps, theta, tmp, rows - 1, T, X, Y, TH, V, W, headings);
    for (k = 0; k < k_steps; k++) {
        const double t = run_time(t_b, t_a, k_steps, k);
        const double t_next = run_time(t_b, t_a, k_steps, k + 1);
        PtSample s;
        pt_rk4_step(driven, &rates, t, theta, nb, t_next - t, work + nb); /* h < 0: backward */
        clamped_sample(&ref, t_next, t_a, t_end_eps, &s);
        theta[nb - 1] = s.theta;
        pull_row(model, &ref, t_next, t_a, t_end_eps, theta, tmp, rows - 2 - k, T, X, Y, TH, V, W,
                 headings);
    }
    return PT_OK;
}

/* np.searchsorted(a, x, side="right") over a[lo..hi-1], returned relative to lo. */
static int search_right(const double *a, int lo, int hi, double x) {
    return bisect_right(a + lo, hi - lo, x);
}

int pt_leader_sample(const PtLeader *g, double t, PtSample *out) {
    int lo, hi, j, k, rows;
    double tc, a;
    const double *ts;
    if (g == NULL || out == NULL || g->n_runs < 0 ||
        (g->n_runs > 0 && (g->offset == NULL || g->t == NULL || g->x == NULL || g->y == NULL ||
                           g->theta == NULL || g->v == NULL || g->w == NULL))) {
        return PT_ERR_ARGUMENT;
    }
    if (g->n_runs == 0) {
        return PT_ERR_NOT_IN_PULL;
    }
    /* j = max(bisect_right(starts, t) - 1, 0) */
    lo = 0;
    hi = g->n_runs;
    while (lo < hi) {
        int mid = (lo + hi) / 2;
        if (t < g->t[g->offset[mid]]) {
            hi = mid;
        } else {
            lo = mid + 1;
        }
    }
    j = lo - 1 < 0 ? 0 : lo - 1;
    if (j + 1 < g->n_runs && t - g->t[g->offset[j + 1] - 1] > g->t[g->offset[j + 1]] - t) {
        j += 1;
    }
    lo = g->offset[j];
    hi = g->offset[j + 1];
    rows = hi - lo;
    if (rows < 2) {
        return PT_ERR_ARGUMENT;
    }
    ts = g->t + lo;
    if (!(ts[0] - 1e-6 <= t && t <= ts[rows - 1] + 1e-6)) {
        return PT_ERR_NOT_IN_PULL;
    }
    tc = py_min(py_max(t, ts[0]), ts[rows - 1]);
    k = search_right(g->t, lo, hi, tc) - 1;
    if (k < 0) {
        k = 0;
    }
    if (k > rows - 2) {
        k = rows - 2;
    }
    a = (ts[k + 1] > ts[k]) ? (tc - ts[k]) / (ts[k + 1] - ts[k]) : 0.0;
    k += lo;
    out->x = (1.0 - a) * g->x[k] + a * g->x[k + 1];
    out->y = (1.0 - a) * g->y[k] + a * g->y[k + 1];
    out->theta = (1.0 - a) * g->theta[k] + a * g->theta[k + 1];
    out->v = (1.0 - a) * g->v[k] + a * g->v[k + 1];
    out->w = (1.0 - a) * g->w[k] + a * g->w[k + 1];
    out->direction = PT_PULL;
    return PT_OK;
}

/* ------------------------------------------------------------------ one control instant */

int pt_instant(const PtController *c, PtControlState *state, const PtReference *reference,
               const PtLeader *leader, double t, const PtMeasurement *m, PtSample *sample,
               double cmd[2], PtControlInfo *info) {
    PtSample robot;
    int status = pt_reference_sample(reference, t, sample);
    if (status != PT_OK) {
        return status;
    }
    if (sample->direction == PT_PULL && leader != NULL) {
        status = pt_leader_sample(leader, t, &robot);
        if (status != PT_OK) {
            return status;
        }
        return pt_command(c, state, t, m, sample, &robot, cmd, info);
    }
    return pt_command(c, state, t, m, sample, NULL, cmd, info);
}

int pt_track(PtTrack *k) {
    if (k == NULL) {
        return PT_ERR_ARGUMENT;
    }
    return pt_instant(k->controller, k->state, k->reference, k->leader, k->t, &k->m, &k->sample,
                      k->cmd, &k->info);
}
