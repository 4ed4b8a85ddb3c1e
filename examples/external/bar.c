/*
 * The 1-D elastic bar (model `bar-1d`) as a cosim node written in C, on the participant
 * library's C ABI (participant-c/include/cosim_participant.h).
 *
 * The same discretisation as the built-in `solid-node` model `bar-1d` (solid-node/src/bar.rs):
 * a lumped-mass spring chain advanced by central differences,
 *     a_n = M^-1 (f_int(u_n) + f_ext + f_coupling),  v_{n+1/2} = v_{n-1/2} + dt a_n,
 *     u_{n+1} = u_n + dt v_{n+1/2},
 * with the same parameters, interfaces and coupling behaviour (docs/architecture.md, kinematic:
 * driver or responder). Build: `make -C examples/external` (after `cargo build --release`).
 */
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cosim_participant.h"

enum { LEFT = 0, RIGHT = 1, NONE = 2 };
#define MAX_IFACES 4

typedef struct {
    char name[64];
    int end;
} Iface;

typedef struct {
    char name[64];
    int end;
    CosimRole role;
    double force, added_stiffness;
} Coupled;

typedef struct {
    double length, x0, young, density, area, tip_force, courant;
    long elements;
    int fixed, load;
    Iface ifaces[MAX_IFACES];
    int n_ifaces;
    /* State: n = elements + 1 nodes. */
    size_t n;
    double h, k, dt;
    double *m, *u, *v, *f;
    double external_work, interface_work, external_impulse, applied_impulse, interface_impulse;
    Coupled coupled[MAX_IFACES];
    int n_coupled;
} Bar;

static const char *FIELDS = "position,velocity,force,mass,stiffness";

/* Report an error through the call (the callback then fails with it); returns 1. */
static int fail(CosimCall *call, CosimErrorKind kind, const char *key, const char *fmt, ...) {
    char msg[256];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    cosim_set_error(call, kind, key, msg);
    return 1;
}

/* A required positive number. */
static int positive(CosimCall *call, const char *key, double *out) {
    int rc = cosim_param_f64(call, key, out);
    if (rc == COSIM_ERROR) return 1;
    if (rc == COSIM_MISSING) return fail(call, COSIM_ERROR_KIND_CONFIG, key, "missing");
    if (!(isfinite(*out) && *out > 0)) return fail(call, COSIM_ERROR_KIND_CONFIG, key, "must be > 0, got %g", *out);
    return 0;
}

static int optional_number(CosimCall *call, const char *key, double *out, double dflt) {
    int rc = cosim_param_f64(call, key, out);
    if (rc == COSIM_MISSING) *out = dflt;
    return rc == COSIM_ERROR;
}

/* "left" | "right" (| "none" when allowed) at `key`, `dflt` when missing. */
static int end_param(CosimCall *call, const char *key, int *out, int dflt, int allow_none) {
    const char *s = NULL;
    int rc = cosim_param_str(call, key, &s);
    if (rc == COSIM_ERROR) return 1;
    if (rc == COSIM_MISSING) { *out = dflt; return 0; }
    if (strcmp(s, "left") == 0) *out = LEFT;
    else if (strcmp(s, "right") == 0) *out = RIGHT;
    else if (allow_none && strcmp(s, "none") == 0) *out = NONE;
    else return fail(call, COSIM_ERROR_KIND_CONFIG, key, "must be \"left\", \"right\"%s, got \"%s\"",
                     allow_none ? " or \"none\"" : "", s);
    return 0;
}

static size_t node_of(const Bar *b, int end) { return end == LEFT ? 0 : (size_t)b->elements; }

static int create(void *user, const char *model, CosimCall *call) {
    Bar *b = user;
    if (strcmp(model, "bar-1d") != 0)
        return fail(call, COSIM_ERROR_KIND_CONFIG, "model", "this solver has one model, \"bar-1d\"; got \"%s\"", model);
    if (positive(call, "length", &b->length) || positive(call, "young", &b->young) ||
        positive(call, "density", &b->density) || positive(call, "area", &b->area))
        return 1;
    if (optional_number(call, "x0", &b->x0, 0.0) || optional_number(call, "tip_force", &b->tip_force, 0.0) ||
        optional_number(call, "courant", &b->courant, 0.9))
        return 1;
    int64_t ne = 0;
    int rc = cosim_param_i64(call, "elements", &ne);
    if (rc == COSIM_ERROR) return 1;
    if (rc == COSIM_MISSING || ne < 1) return fail(call, COSIM_ERROR_KIND_CONFIG, "elements", "must be an integer >= 1");
    b->elements = (long)ne;
    if (!(b->courant > 0 && b->courant <= 1))
        return fail(call, COSIM_ERROR_KIND_CONFIG, "courant", "must be in (0, 1], got %g", b->courant);
    if (!isfinite(b->tip_force)) return fail(call, COSIM_ERROR_KIND_CONFIG, "tip_force", "must be finite");
    if (end_param(call, "fixed", &b->fixed, LEFT, 1) || end_param(call, "load_end", &b->load, RIGHT, 1)) return 1;
    /* interfaces = { name = "left" | "right", ... } */
    for (size_t i = 0;; i++) {
        const char *name = NULL;
        rc = cosim_param_table_key(call, "interfaces", i, &name);
        if (rc == COSIM_ERROR) return 1;
        if (rc == COSIM_MISSING) break;
        if (b->n_ifaces == MAX_IFACES || strlen(name) >= sizeof b->ifaces[0].name)
            return fail(call, COSIM_ERROR_KIND_CONFIG, "interfaces", "at most %d interfaces of < 64 characters", MAX_IFACES);
        char key[80];
        snprintf(key, sizeof key, "interfaces.%s", name);
        Iface *f = &b->ifaces[b->n_ifaces++];
        strcpy(f->name, name);
        if (end_param(call, key, &f->end, NONE, 0)) return 1;
    }
    b->n = (size_t)b->elements + 1;
    b->h = b->length / (double)b->elements;
    b->k = b->young * b->area / b->h;
    double me = b->density * b->area * b->h;
    b->m = malloc(b->n * sizeof(double));
    b->u = calloc(b->n, sizeof(double));
    b->v = calloc(b->n, sizeof(double));
    b->f = calloc(b->n, sizeof(double));
    if (!b->m || !b->u || !b->v || !b->f) return fail(call, COSIM_ERROR_KIND_OTHER, NULL, "out of memory");
    for (size_t i = 0; i < b->n; i++) b->m[i] = me;
    b->m[0] = me / 2.0;
    b->m[b->n - 1] = me / 2.0;
    return 0;
}

static int describe(void *user, CosimCall *call) {
    Bar *b = user;
    cosim_describe_model(call, "bar-1d", "SI");
    for (int i = 0; i < b->n_ifaces; i++) cosim_describe_interface(call, b->ifaces[i].name, 1, FIELDS, FIELDS);
    return 0;
}

static const Iface *find_iface(const Bar *b, const char *name) {
    for (int i = 0; i < b->n_ifaces; i++)
        if (strcmp(b->ifaces[i].name, name) == 0) return &b->ifaces[i];
    return NULL;
}

static int interface_mesh(void *user, const char *name, CosimCall *call) {
    Bar *b = user;
    const Iface *f = find_iface(b, name);
    if (!f) return fail(call, COSIM_ERROR_KIND_INTERFACE, name, "no such interface on this bar (see params.interfaces)");
    double xyz[3] = {f->end == LEFT ? b->x0 : b->x0 + b->length, 0.0, 0.0};
    return cosim_mesh_points(call, xyz, 1) != COSIM_OK;
}

/* Spring-chain internal force on every node, into b->f. */
static void internal_force(Bar *b) {
    memset(b->f, 0, b->n * sizeof(double));
    for (size_t i = 0; i + 1 < b->n; i++) {
        double d = b->k * (b->u[i + 1] - b->u[i]);
        b->f[i] += d;
        b->f[i + 1] -= d;
    }
}

/* Gershgorin bound ω² ≤ max 2 Σk/m (exact for a uniform chain: dt = h/c); a driven end counts
 * the responder's mass and stiffness bound. */
static double critical_dt(const Bar *b) {
    double w2 = 0.0;
    for (size_t i = 0; i < b->n; i++) {
        double ksum = (i == 0 || i == b->n - 1) ? b->k : 2.0 * b->k;
        if (b->n == 1) ksum = 0.0;
        for (int c = 0; c < b->n_coupled; c++)
            if (b->coupled[c].role == COSIM_ROLE_DRIVER && node_of(b, b->coupled[c].end) == i)
                ksum += b->coupled[c].added_stiffness;
        double w = 2.0 * ksum / b->m[i];
        if (w > w2) w2 = w;
    }
    return 2.0 / sqrt(w2);
}

/* A received field with `size` values, or NULL after reporting it. */
static const double *require(CosimCall *call, const char *iface, const char *name, size_t size) {
    size_t len = 0;
    const double *p = cosim_inbox_get(call, iface, name, NULL, &len);
    if (!p) { fail(call, COSIM_ERROR_KIND_INTERFACE, iface, "no '%s' field received", name); return NULL; }
    if (len != size) { fail(call, COSIM_ERROR_KIND_INTERFACE, iface, "'%s' has %zu values, expected %zu", name, len, size); return NULL; }
    return p;
}

static int setup(void *user, CosimCall *call) {
    Bar *b = user;
    b->n_coupled = 0;
    size_t nb = cosim_binding_count(call);
    for (size_t j = 0; j < nb; j++) {
        CosimBinding bd;
        if (cosim_binding_get(call, j, &bd) != COSIM_OK) return 1;
        const Iface *f = find_iface(b, bd.interface);
        if (!f) return fail(call, COSIM_ERROR_KIND_INTERFACE, bd.interface, "no such interface on this bar");
        if (f->end == b->fixed) return fail(call, COSIM_ERROR_KIND_INTERFACE, bd.interface, "is the fixed end and cannot be coupled");
        Coupled *c = &b->coupled[b->n_coupled++];
        memset(c, 0, sizeof *c);
        strcpy(c->name, f->name);
        c->end = f->end;
        c->role = bd.role;
    }
    internal_force(b);
    for (int j = 0; j < b->n_coupled; j++) {
        Coupled *c = &b->coupled[j];
        size_t i = node_of(b, c->end);
        if (c->role == COSIM_ROLE_RESPONDER) {
            /* The kinematic responder's set-up: interface mass, stiffness bound, force at t0. */
            double *m = cosim_outbox_put(call, c->name, "mass", 1, 1);
            double *k = cosim_outbox_put(call, c->name, "stiffness", 1, 1);
            double *fo = cosim_outbox_put(call, c->name, "force", 3, 1);
            if (!m || !k || !fo) return 1;
            m[0] = b->m[i];
            k[0] = b->k;
            fo[0] = b->f[i], fo[1] = 0.0, fo[2] = 0.0;
        } else {
            const double *m = require(call, c->name, "mass", 1);
            const double *k = require(call, c->name, "stiffness", 1);
            const double *fo = require(call, c->name, "force", 3);
            if (!m || !k || !fo) return 1;
            if (!(m[0] >= 0 && k[0] >= 0 && isfinite(m[0]) && isfinite(k[0])))
                return fail(call, COSIM_ERROR_KIND_INTERFACE, c->name, "bad set-up mass %g or stiffness %g", m[0], k[0]);
            b->m[i] += m[0];
            c->added_stiffness = k[0];
            c->force = fo[0];
        }
    }
    b->dt = b->courant * critical_dt(b);
    return 0;
}

static double stable_dt(void *user) {
    Bar *b = user;
    return b->dt > 0 ? b->dt : b->courant * critical_dt(b);
}

static int prescribed(const Bar *b, size_t i) {
    if (b->fixed != NONE && node_of(b, b->fixed) == i) return 1;
    for (int c = 0; c < b->n_coupled; c++)
        if (b->coupled[c].role == COSIM_ROLE_RESPONDER && node_of(b, b->coupled[c].end) == i) return 1;
    return 0;
}

static int advance(void *user, const CosimWindow *w, CosimCall *call, CosimStepReport *r) {
    Bar *b = user;
    double span = w->t1 - w->t0;
    if (!(span > 0)) return fail(call, COSIM_ERROR_KIND_OTHER, NULL, "empty window [%g, %g]", w->t0, w->t1);
    double ns = ceil(span / stable_dt(b) - 1e-9);
    uint64_t nsub = ns < 1.0 ? 1 : (uint64_t)ns;
    double dt = span / (double)nsub;
    /* This window's inputs: the driver's force, or the responder's prescribed velocity. */
    size_t imp_node[MAX_IFACES];
    double imp_u0[MAX_IFACES], imp_vel[MAX_IFACES];
    int n_imp = 0;
    for (int j = 0; j < b->n_coupled; j++) {
        Coupled *c = &b->coupled[j];
        size_t i = node_of(b, c->end);
        if (c->role == COSIM_ROLE_DRIVER) {
            const double *fo = require(call, c->name, "force", 3);
            if (!fo) return 1;
            c->force = fo[0];
        } else {
            const double *vel = require(call, c->name, "velocity", 3);
            if (!vel) return 1;
            if (!isfinite(vel[0])) return fail(call, COSIM_ERROR_KIND_INTERFACE, c->name, "non-finite velocity received");
            imp_node[n_imp] = i, imp_u0[n_imp] = b->u[i], imp_vel[n_imp] = vel[0];
            n_imp++;
        }
    }
    size_t fixed = b->fixed == NONE ? (size_t)-1 : node_of(b, b->fixed);
    size_t load = b->load == NONE ? (size_t)-1 : node_of(b, b->load);
    double fl = b->tip_force;
    for (uint64_t step = 0; step < nsub; step++) {
        internal_force(b);
        if (fixed != (size_t)-1) b->external_impulse += -b->f[fixed] * dt; /* support reaction */
        for (int j = 0; j < b->n_coupled; j++) {
            Coupled *c = &b->coupled[j];
            size_t i = node_of(b, c->end);
            if (c->role == COSIM_ROLE_DRIVER) {
                b->f[i] += c->force;
                b->interface_impulse += c->force * dt;
            } else {
                b->interface_impulse += -b->f[i] * dt;
            }
        }
        if (load != (size_t)-1) {
            b->f[load] += fl;
            b->external_impulse += fl * dt;
            b->applied_impulse += fabs(fl) * dt;
        }
        for (size_t i = 0; i < b->n; i++) b->v[i] += dt * (b->f[i] / b->m[i]);
        if (fixed != (size_t)-1) b->v[fixed] = 0.0;
        for (int j = 0; j < n_imp; j++) b->v[imp_node[j]] = imp_vel[j];
        for (int j = 0; j < b->n_coupled; j++) {
            Coupled *c = &b->coupled[j];
            size_t i = node_of(b, c->end);
            double du = dt * b->v[i];
            b->interface_work += (c->role == COSIM_ROLE_DRIVER ? c->force : -b->f[i]) * du;
        }
        if (load != (size_t)-1) b->external_work += fl * dt * b->v[load];
        for (size_t i = 0; i < b->n; i++) b->u[i] += dt * b->v[i];
        /* Along the driver's motion (seed 004 eq. 31), from the window start: no drift. */
        for (int j = 0; j < n_imp; j++) b->u[imp_node[j]] = imp_u0[j] + (double)(step + 1) * dt * imp_vel[j];
    }
    /* Outputs at t1. */
    internal_force(b);
    if (load != (size_t)-1) cosim_report_scalar(call, "tip_displacement", b->u[load]);
    for (int j = 0; j < b->n_coupled; j++) {
        Coupled *c = &b->coupled[j];
        size_t i = node_of(b, c->end);
        if (c->role == COSIM_ROLE_DRIVER) {
            double x_ref = c->end == LEFT ? b->x0 : b->x0 + b->length;
            double *p = cosim_outbox_put(call, c->name, "position", 3, 1);
            double *v = cosim_outbox_put(call, c->name, "velocity", 3, 1);
            if (!p || !v) return 1;
            p[0] = x_ref + b->u[i], p[1] = 0.0, p[2] = 0.0;
            v[0] = b->v[i], v[1] = 0.0, v[2] = 0.0;
        } else {
            double *fo = cosim_outbox_put(call, c->name, "force", 3, 1);
            if (!fo) return 1;
            fo[0] = b->f[i], fo[1] = 0.0, fo[2] = 0.0;
        }
        char name[80];
        snprintf(name, sizeof name, "%s_displacement", c->name);
        cosim_report_scalar(call, name, b->u[i]);
    }
    double ke = 0.0, ie = 0.0, p = 0.0, gross = 0.0;
    for (size_t i = 0; i < b->n; i++) {
        if (prescribed(b, i)) continue;
        ke += 0.5 * b->m[i] * b->v[i] * b->v[i];
        p += b->m[i] * b->v[i];
        gross += b->m[i] * fabs(b->v[i]);
    }
    for (size_t i = 0; i + 1 < b->n; i++) {
        double d = b->u[i + 1] - b->u[i];
        ie += 0.5 * b->k * d * d;
    }
    r->kinetic_energy = ke;
    r->internal_energy = ie;
    r->external_work = b->external_work;
    r->interface_work = b->interface_work;
    r->momentum[0] = p;
    r->momentum_gross = gross;
    r->external_impulse[0] = b->external_impulse;
    r->applied_impulse = b->applied_impulse;
    r->interface_impulse[0] = b->interface_impulse;
    r->substeps = nsub;
    return 0;
}

/* Checkpoints: a header (magic, format version, nodes, couplings), then u, v, the five work
 * and impulse sums and each coupling's force, as doubles in the host's byte order (a restart
 * runs on the host that wrote them). Masses, step and roles come again from setup(). */
static const char STATE_MAGIC[8] = {'B', 'A', 'R', 'C', 'S', 'T', '0', '1'};
enum { STATE_VERSION = 1 };
typedef struct {
    char magic[8];
    uint32_t version, couplings;
    uint64_t nodes;
} StateHeader;

static int save_state(void *user, CosimCall *call) {
    Bar *b = user;
    StateHeader h = {.version = STATE_VERSION, .couplings = (uint32_t)b->n_coupled, .nodes = b->n};
    memcpy(h.magic, STATE_MAGIC, sizeof h.magic);
    double sums[5] = {b->external_work, b->interface_work, b->external_impulse, b->applied_impulse,
                      b->interface_impulse};
    double forces[MAX_IFACES];
    for (int j = 0; j < b->n_coupled; j++) forces[j] = b->coupled[j].force;
    int rc = cosim_state_write(call, (const uint8_t *)&h, sizeof h);
    rc = rc || cosim_state_write(call, (const uint8_t *)b->u, b->n * sizeof(double));
    rc = rc || cosim_state_write(call, (const uint8_t *)b->v, b->n * sizeof(double));
    rc = rc || cosim_state_write(call, (const uint8_t *)sums, sizeof sums);
    rc = rc || cosim_state_write(call, (const uint8_t *)forces, (size_t)b->n_coupled * sizeof(double));
    return rc != COSIM_OK;
}

/* Restore what save_state wrote, after setup: another format, version, mesh or coupling set is
 * refused before anything is overwritten. */
static int load_state(void *user, const uint8_t *bytes, size_t len, CosimCall *call) {
    Bar *b = user;
    StateHeader h;
    if (len < sizeof h) return fail(call, COSIM_ERROR_KIND_OTHER, NULL, "bar state of %zu bytes is too short", len);
    memcpy(&h, bytes, sizeof h);
    if (memcmp(h.magic, STATE_MAGIC, sizeof h.magic) != 0)
        return fail(call, COSIM_ERROR_KIND_OTHER, NULL, "not a state of this bar (bad magic)");
    if (h.version != STATE_VERSION)
        return fail(call, COSIM_ERROR_KIND_OTHER, NULL, "bar state version %u, this bar reads %d", h.version, STATE_VERSION);
    if (h.nodes != b->n || h.couplings != (uint32_t)b->n_coupled)
        return fail(call, COSIM_ERROR_KIND_OTHER, NULL, "state of %llu nodes and %u couplings, this bar has %zu and %d",
                    (unsigned long long)h.nodes, h.couplings, b->n, b->n_coupled);
    size_t count = 2 * b->n + 5 + (size_t)b->n_coupled;
    if (len != sizeof h + count * sizeof(double))
        return fail(call, COSIM_ERROR_KIND_OTHER, NULL, "bar state of %zu bytes, expected %zu", len, sizeof h + count * sizeof(double));
    const uint8_t *p = bytes + sizeof h;
    memcpy(b->u, p, b->n * sizeof(double)), p += b->n * sizeof(double);
    memcpy(b->v, p, b->n * sizeof(double)), p += b->n * sizeof(double);
    double sums[5];
    memcpy(sums, p, sizeof sums), p += sizeof sums;
    b->external_work = sums[0], b->interface_work = sums[1], b->external_impulse = sums[2];
    b->applied_impulse = sums[3], b->interface_impulse = sums[4];
    for (int j = 0; j < b->n_coupled; j++, p += sizeof(double)) memcpy(&b->coupled[j].force, p, sizeof(double));
    internal_force(b);
    return 0;
}

static void destroy(void *user) {
    Bar *b = user;
    free(b->m), free(b->u), free(b->v), free(b->f);
}

int main(int argc, char **argv) {
    static Bar bar; /* zeroed */
    CosimSolverVTable vt = {
        .abi_version = COSIM_ABI_VERSION,
        .create = create,
        .describe = describe,
        .interface_mesh = interface_mesh,
        .setup = setup,
        .stable_dt = stable_dt,
        .advance = advance,
        .save_state = save_state,
        .load_state = load_state,
        .destroy = destroy,
    };
    return cosim_node_main(argc, (const char *const *)argv, &vt, &bar);
}
