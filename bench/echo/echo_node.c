/* Benchmark helper: the `echo` node of target/release/cosim-echo-node written in C on the
 * participant library, for the participant window benchmark (`cosim bench --only window`,
 * which carries this file inside the binary and compiles it with `cc` when one exists). By hand:
 *   cc -O2 -I participant-c/include -o echo-node-c bench/echo/echo_node.c \
 *      -L target/release -lcosim_participant -Wl,-rpath,$PWD/target/release
 */
#include <string.h>

#include "cosim_participant.h"

typedef struct {
    int64_t points;
    CosimRole role;
    int coupled;
} Echo;

static int create(void *user, const char *model, CosimCall *call) {
    Echo *e = user;
    if (strcmp(model, "echo") != 0) {
        cosim_set_error(call, COSIM_ERROR_KIND_CONFIG, "model", "only \"echo\"");
        return 1;
    }
    if (cosim_param_i64(call, "points", &e->points) == COSIM_MISSING) e->points = 128;
    return 0;
}

static int describe(void *user, CosimCall *call) {
    Echo *e = user;
    return cosim_describe_interface(call, "port", (size_t)e->points, "signal,echo", "signal,echo");
}

static int interface_mesh(void *user, const char *name, CosimCall *call) {
    Echo *e = user;
    (void)name;
    double xyz[3 * 4096];
    if (e->points > 4096) return 1;
    for (int64_t i = 0; i < e->points; i++) xyz[3 * i] = (double)i, xyz[3 * i + 1] = 0, xyz[3 * i + 2] = 0;
    return cosim_mesh_points(call, xyz, (size_t)e->points);
}

static int setup(void *user, CosimCall *call) {
    Echo *e = user;
    CosimBinding b;
    e->coupled = cosim_binding_get(call, 0, &b) == COSIM_OK;
    if (e->coupled) e->role = b.role;
    return 0;
}

static double stable_dt(void *user) {
    (void)user;
    return 1.0;
}

static int advance(void *user, const CosimWindow *w, CosimCall *call, CosimStepReport *r) {
    Echo *e = user;
    size_t n = (size_t)e->points;
    if (e->coupled && e->role == COSIM_ROLE_RESPONDER) {
        size_t len = 0;
        const double *v = cosim_inbox_get(call, "port", "signal", NULL, &len);
        double *f = cosim_outbox_put(call, "port", "echo", 1, n);
        if (!v || !f || len != n) return 1;
        memcpy(f, v, n * sizeof(double));
    } else if (e->coupled) {
        double *v = cosim_outbox_put(call, "port", "signal", 1, n);
        if (!v) return 1;
        for (size_t i = 0; i < n; i++) v[i] = (double)w->index;
    }
    r->substeps = 1;
    return 0;
}

int main(int argc, char **argv) {
    static Echo echo;
    CosimSolverVTable vt = {
        .abi_version = COSIM_ABI_VERSION,
        .create = create,
        .describe = describe,
        .interface_mesh = interface_mesh,
        .setup = setup,
        .stable_dt = stable_dt,
        .advance = advance,
    };
    return cosim_node_main(argc, (const char *const *)argv, &vt, &echo);
}
