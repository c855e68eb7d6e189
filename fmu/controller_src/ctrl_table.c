/*
 * The resource URI and the mission table of the BackwardController FMU (see ctrl_table.h).
 */
#include <ctype.h>
#include <locale.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "ctrl_table.h"

#define TOKEN_LEN 128

/* ---------------------------------------------------------------- the resource URI */

static int hex_value(char c) {
    if (c >= '0' && c <= '9') {
        return c - '0';
    }
    if (c >= 'a' && c <= 'f') {
        return c - 'a' + 10;
    }
    if (c >= 'A' && c <= 'F') {
        return c - 'A' + 10;
    }
    return -1;
}

int ctrl_resource_path(const char *uri, const char *file, char *path, size_t len, char *msg,
                       size_t msg_len) {
    const char *p;
    size_t k = 0;
    if (uri == NULL || uri[0] == '\0') {
        snprintf(msg, msg_len, "fmuResourceLocation is empty: the controller needs its mission "
                 "table resources/%s", file);
        return 0;
    }
    if (strncmp(uri, "file:", 5) != 0 && strncmp(uri, "FILE:", 5) != 0) {
        snprintf(msg, msg_len, "fmuResourceLocation = '%s': only file: URIs are supported", uri);
        return 0;
    }
    p = uri + 5;
    if (p[0] == '/' && p[1] == '/' && p[2] != '/') { /* file://host/path: an authority */
        const char *host = p + 2;
        const char *end = strchr(host, '/');
        if (end == NULL || !((end == host) || (end - host == 9
                                                && strncmp(host, "localhost", 9) == 0))) {
            snprintf(msg, msg_len, "fmuResourceLocation = '%s': a file on another host is not "
                     "a local resource folder", uri);
            return 0;
        }
        p = end;
    }
    while (p[0] == '/' && p[1] == '/') { /* file:////tmp (ecos), file:///tmp: one slash */
        p++;
    }
    if (p[0] == '/' && isalpha((unsigned char)p[1]) && p[2] == ':') { /* file:///C:/dir */
        p++;
    }
    for (; *p != '\0'; p++) {
        char c = *p;
        if (c == '%') {
            int hi = hex_value(p[1]), lo = (hi < 0) ? -1 : hex_value(p[2]);
            if (hi < 0 || lo < 0) {
                snprintf(msg, msg_len, "fmuResourceLocation = '%s': bad percent-encoding at "
                         "'%.3s'", uri, p);
                return 0;
            }
            c = (char)(16 * hi + lo);
            p += 2;
            if (c == '\0') {
                snprintf(msg, msg_len, "fmuResourceLocation = '%s': %%00 in a path", uri);
                return 0;
            }
        }
        if (k + 1 >= len) {
            snprintf(msg, msg_len, "fmuResourceLocation = '%s': the path is too long", uri);
            return 0;
        }
        path[k++] = c;
    }
    if (k > 0 && path[k - 1] == '/') {
        k--;
    }
    if (k + 1 + strlen(file) + 1 > len) {
        snprintf(msg, msg_len, "fmuResourceLocation = '%s': the path is too long", uri);
        return 0;
    }
    path[k++] = '/';
    strcpy(path + k, file);
    return 1;
}

/* ---------------------------------------------------------------- tokens */

typedef struct {
    const char *text;
    size_t pos;
    int line;      /* line of the last token */
    const char *path;
    char *msg;
    size_t msg_len;
} Reader;

static int fail(Reader *r, const char *fmt, ...) {
    char buffer[CTRL_MSG_LEN];
    va_list args;
    va_start(args, fmt);
    vsnprintf(buffer, sizeof(buffer), fmt, args);
    va_end(args);
    snprintf(r->msg, r->msg_len, "%s:%d: %s", r->path, r->line, buffer);
    return 0;
}

/* The next whitespace-separated token outside comments into out; 0 at the end of the text. */
static int next_token(Reader *r, char *out) {
    const char *s = r->text;
    size_t k = 0;
    for (;;) {
        while (s[r->pos] != '\0' && isspace((unsigned char)s[r->pos])) {
            if (s[r->pos] == '\n') {
                r->line++;
            }
            r->pos++;
        }
        if (s[r->pos] != '#') {
            break;
        }
        while (s[r->pos] != '\0' && s[r->pos] != '\n') {
            r->pos++;
        }
    }
    if (s[r->pos] == '\0') {
        return 0;
    }
    while (s[r->pos] != '\0' && !isspace((unsigned char)s[r->pos]) && s[r->pos] != '#') {
        if (k + 1 < TOKEN_LEN) {
            out[k++] = s[r->pos];
        }
        r->pos++;
    }
    out[k] = '\0';
    return 1;
}

static int expect_word(Reader *r, const char *word) {
    char token[TOKEN_LEN];
    if (!next_token(r, token)) {
        return fail(r, "the table ends where '%s' was expected", word);
    }
    if (strcmp(token, word) != 0) {
        return fail(r, "'%s' where '%s' was expected", token, word);
    }
    return 1;
}

/* strtod in the "C" locale's syntax whatever the process locale (the table says 0.5). */
static int parse_double(const char *token, double *value) {
    char buffer[TOKEN_LEN];
    const char *point = localeconv()->decimal_point;
    const char *text = token;
    char *end;
    if (point != NULL && strcmp(point, ".") != 0 && strlen(point) == 1) {
        size_t k;
        for (k = 0; token[k] != '\0' && k + 1 < sizeof(buffer); k++) {
            buffer[k] = (token[k] == '.') ? point[0] : token[k];
        }
        buffer[k] = '\0';
        text = buffer;
    }
    *value = strtod(text, &end);
    return end != text && *end == '\0' && isfinite(*value);
}

static int read_double(Reader *r, const char *what, double *value) {
    char token[TOKEN_LEN];
    if (!next_token(r, token)) {
        return fail(r, "the table ends where %s was expected", what);
    }
    if (!parse_double(token, value)) {
        return fail(r, "%s = '%s': must be a finite number", what, token);
    }
    return 1;
}

static int read_count(Reader *r, const char *what, int lo, int hi, int *value) {
    char token[TOKEN_LEN];
    char *end;
    long v;
    if (!next_token(r, token)) {
        return fail(r, "the table ends where %s was expected", what);
    }
    v = strtol(token, &end, 10);
    if (end == token || *end != '\0' || v < lo || v > hi) {
        return fail(r, "%s = '%s': must be an integer from %d to %d", what, token, lo, hi);
    }
    *value = (int)v;
    return 1;
}

static int read_choice(Reader *r, const char *what, const char *a, const char *b, int *which) {
    char token[TOKEN_LEN];
    if (!next_token(r, token)) {
        return fail(r, "the table ends where %s was expected", what);
    }
    if (strcmp(token, a) == 0 || strcmp(token, b) == 0) {
        *which = (strcmp(token, a) == 0) ? 0 : 1;
        return 1;
    }
    return fail(r, "%s = '%s': allowed are '%s' and '%s'", what, token, a, b);
}

/* ---------------------------------------------------------------- the table */

static char *read_file(const char *path, char *msg, size_t msg_len) {
    FILE *f = fopen(path, "rb");
    char *text;
    long size;
    if (f == NULL) {
        snprintf(msg, msg_len, "cannot open the mission table '%s' (export the FMU with "
                 "pushtrain export-ssp, which writes it into resources/)", path);
        return NULL;
    }
    if (fseek(f, 0, SEEK_END) != 0 || (size = ftell(f)) < 0 || fseek(f, 0, SEEK_SET) != 0
        || size > 256L * 1024 * 1024) {
        fclose(f);
        snprintf(msg, msg_len, "cannot read the mission table '%s'", path);
        return NULL;
    }
    text = (char *)malloc((size_t)size + 1);
    if (text == NULL || fread(text, 1, (size_t)size, f) != (size_t)size) {
        free(text);
        fclose(f);
        snprintf(msg, msg_len, "cannot read the mission table '%s' (%ld bytes)", path, size);
        return NULL;
    }
    fclose(f);
    text[size] = '\0';
    return text;
}

static int read_header(Reader *r, CtrlTable *t) {
    int format = 0, k;
    if (!expect_word(r, "pushtrain-reference") || !read_count(r, "format", 1, 1000, &format)) {
        return 0;
    }
    if (format != CTRL_TABLE_FORMAT) {
        return fail(r, "table format %d: this FMU reads format %d", format, CTRL_TABLE_FORMAT);
    }
    if (!expect_word(r, "start")) {
        return 0;
    }
    for (k = 0; k < 3; k++) {
        if (!read_double(r, k == 0 ? "start x" : (k == 1 ? "start y" : "start theta"),
                         &t->start[k])) {
            return 0;
        }
    }
    if (!expect_word(r, "t0") || !read_double(r, "t0", &t->t0) || !expect_word(r, "speed")
        || !read_double(r, "speed", &t->speed) || !expect_word(r, "cusp_dwell")
        || !read_double(r, "cusp_dwell", &t->cusp_dwell)) {
        return 0;
    }
    if (!(t->speed > 0.0)) {
        return fail(r, "speed = %g m/s: must be > 0", t->speed);
    }
    if (!(t->cusp_dwell >= 0.0)) {
        return fail(r, "cusp_dwell = %g s: must be >= 0", t->cusp_dwell);
    }
    return 1;
}

static int read_segments(Reader *r, CtrlTable *t) {
    int k;
    if (!expect_word(r, "segments") || !read_count(r, "segments", 1, 1000000, &t->n_segments)) {
        return 0;
    }
    t->segments = (PtSegment *)calloc((size_t)t->n_segments, sizeof(PtSegment));
    if (t->segments == NULL) {
        return fail(r, "out of memory for %d segments", t->n_segments);
    }
    for (k = 0; k < t->n_segments; k++) {
        PtSegment *s = &t->segments[k];
        int kind = 0, pull = 0;
        if (!read_choice(r, "segment kind", "line", "arc", &kind)
            || !read_double(r, "segment length", &s->length)
            || !read_double(r, "segment curvature", &s->curvature)
            || !read_choice(r, "segment direction", "push", "pull", &pull)
            || !read_double(r, "segment speed", &s->speed)) {
            return 0;
        }
        s->kind = kind ? PT_ARC : PT_LINE;
        s->direction = pull ? PT_PULL : PT_PUSH;
        if (!(s->length > 0.0) || !(s->speed >= 0.0) || (s->kind == PT_LINE) != (s->curvature == 0.0)) {
            return fail(r, "segment %d (length %g m, curvature %g 1/m, speed %g m/s): the length "
                        "must be > 0, the speed >= 0 (0: default), a line has curvature 0 and "
                        "an arc not", k + 1, s->length, s->curvature, s->speed);
        }
    }
    return 1;
}

static int grow(CtrlTable *t, int rows) {
    double **cols[6];
    int c;
    cols[0] = &t->t;
    cols[1] = &t->x;
    cols[2] = &t->y;
    cols[3] = &t->theta;
    cols[4] = &t->v;
    cols[5] = &t->w;
    for (c = 0; c < 6; c++) {
        double *p = (double *)realloc(*cols[c], (size_t)(rows > 0 ? rows : 1) * sizeof(double));
        if (p == NULL) {
            return 0;
        }
        *cols[c] = p;
    }
    return 1;
}

static int read_leader(Reader *r, CtrlTable *t) {
    int j, total = 0;
    if (!expect_word(r, "leader_runs") || !read_count(r, "leader_runs", 0, 1000000, &t->n_runs)) {
        return 0;
    }
    t->offset = (int *)calloc((size_t)t->n_runs + 1, sizeof(int));
    if (t->offset == NULL || !grow(t, 1)) {
        return fail(r, "out of memory for %d leader runs", t->n_runs);
    }
    for (j = 0; j < t->n_runs; j++) {
        int rows = 0, k;
        if (!expect_word(r, "run") || !read_count(r, "run rows", 2, 100000000, &rows)) {
            return 0;
        }
        if (!grow(t, total + rows)) {
            return fail(r, "out of memory for %d leader rows", total + rows);
        }
        for (k = total; k < total + rows; k++) {
            if (!read_double(r, "leader t", &t->t[k]) || !read_double(r, "leader x", &t->x[k])
                || !read_double(r, "leader y", &t->y[k])
                || !read_double(r, "leader theta", &t->theta[k])
                || !read_double(r, "leader v", &t->v[k]) || !read_double(r, "leader w", &t->w[k])) {
                return 0;
            }
            if (k > 0 && !(t->t[k] > t->t[k - 1]) && !(k == total && t->t[k] >= t->t[k - 1])) {
                return fail(r, "leader run %d: t = %.17g after %.17g; times must increase", j + 1,
                            t->t[k], t->t[k - 1]);
            }
        }
        total += rows;
        t->offset[j + 1] = total;
    }
    return 1;
}

int ctrl_table_load(const char *path, CtrlTable *table, char *msg, size_t msg_len) {
    Reader r;
    char token[TOKEN_LEN];
    int ok;
    memset(table, 0, sizeof(*table));
    r.text = read_file(path, msg, msg_len);
    if (r.text == NULL) {
        return 0;
    }
    r.pos = 0;
    r.line = 1;
    r.path = path;
    r.msg = msg;
    r.msg_len = msg_len;
    ok = read_header(&r, table) && read_segments(&r, table) && read_leader(&r, table);
    if (ok && next_token(&r, token)) {
        ok = fail(&r, "'%s' after the last leader run: the table should end there", token);
    }
    free((void *)r.text);
    if (!ok) {
        ctrl_table_free(table);
    }
    return ok;
}

void ctrl_table_free(CtrlTable *table) {
    free(table->segments);
    free(table->offset);
    free(table->t);
    free(table->x);
    free(table->y);
    free(table->theta);
    free(table->v);
    free(table->w);
    memset(table, 0, sizeof(*table));
}
