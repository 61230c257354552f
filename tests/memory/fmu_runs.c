/* A plain C importer of a nudyn FMU, for valgrind: RUNS times, one
 * instance is instantiated, initialized, stepped STEPS times (reading every
 * Real value, saving and restoring FMU states, making a refused call), and
 * freed; then a model exchange instance takes STEPS explicit Euler steps
 * through the continuous-state functions, and is freed. Under valgrind, the
 * memory still in use at exit must not grow with RUNS, and nothing may be
 * lost.
 *
 *   fmu_runs UNZIPPED_FMU_DIR MODEL_IDENTIFIER GUID N_REALS NX RUNS STEPS
 *
 * Exit status 0 when every call returned the expected status and every
 * value read was finite. */

#include <dlfcn.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

typedef void *fmi2Component;
typedef void *fmi2FMUstate;
typedef int fmi2Status;
typedef struct {
    void (*logger)(void *, const char *, fmi2Status, const char *, const char *, ...);
    void *(*allocateMemory)(size_t, size_t);
    void (*freeMemory)(void *);
    void (*stepFinished)(void *, fmi2Status);
    void *componentEnvironment;
} fmi2CallbackFunctions;

enum { fmi2OK = 0, fmi2Error = 3, fmi2ModelExchange = 0, fmi2CoSimulation = 1 };

typedef struct {
    int newDiscreteStatesNeeded, terminateSimulation, nominalsOfContinuousStatesChanged,
        valuesOfContinuousStatesChanged, nextEventTimeDefined;
    double nextEventTime;
} fmi2EventInfo;

static int logged;

static void logger(void *env, const char *name, fmi2Status status, const char *category, const char *message, ...) {
    (void)env, (void)name, (void)status, (void)category, (void)message;
    logged++;
}

static void *symbol(void *library, const char *name) {
    void *f = dlsym(library, name);
    if (!f) {
        fprintf(stderr, "missing symbol %s\n", name);
        exit(2);
    }
    return f;
}

#define CHECK(call, expected)                                                         \
    do {                                                                              \
        fmi2Status status_ = (call);                                                  \
        if (status_ != (expected)) {                                                  \
            fprintf(stderr, "%s returned %d, expected %d\n", #call, status_, expected); \
            return 1;                                                                 \
        }                                                                             \
    } while (0)

int main(int argc, char **argv) {
    if (argc != 8) {
        fprintf(stderr, "usage: %s UNZIPPED_FMU_DIR MODEL_IDENTIFIER GUID N_REALS NX RUNS STEPS\n", argv[0]);
        return 2;
    }
    const char *dir = argv[1], *identifier = argv[2], *guid = argv[3];
    size_t n_reals = strtoul(argv[4], NULL, 10), nx = strtoul(argv[5], NULL, 10);
    int runs = atoi(argv[6]), steps = atoi(argv[7]);

    char path[4096], uri[4096];
    snprintf(path, sizeof path, "%s/binaries/linux64/%s.so", dir, identifier);
    snprintf(uri, sizeof uri, "file://%s/resources/", dir);
    void *library = dlopen(path, RTLD_NOW | RTLD_LOCAL);
    if (!library) {
        fprintf(stderr, "dlopen %s: %s\n", path, dlerror());
        return 2;
    }
    fmi2Component (*instantiate)(const char *, int, const char *, const char *, const fmi2CallbackFunctions *, int, int) =
        symbol(library, "fmi2Instantiate");
    void (*free_instance)(fmi2Component) = symbol(library, "fmi2FreeInstance");
    fmi2Status (*setup)(fmi2Component, int, double, double, int, double) = symbol(library, "fmi2SetupExperiment");
    fmi2Status (*enter)(fmi2Component) = symbol(library, "fmi2EnterInitializationMode");
    fmi2Status (*exit_init)(fmi2Component) = symbol(library, "fmi2ExitInitializationMode");
    fmi2Status (*set_real)(fmi2Component, const unsigned *, size_t, const double *) = symbol(library, "fmi2SetReal");
    fmi2Status (*get_real)(fmi2Component, const unsigned *, size_t, double *) = symbol(library, "fmi2GetReal");
    fmi2Status (*do_step)(fmi2Component, double, double, int) = symbol(library, "fmi2DoStep");
    fmi2Status (*get_state)(fmi2Component, fmi2FMUstate *) = symbol(library, "fmi2GetFMUstate");
    fmi2Status (*set_state)(fmi2Component, fmi2FMUstate) = symbol(library, "fmi2SetFMUstate");
    fmi2Status (*free_state)(fmi2Component, fmi2FMUstate *) = symbol(library, "fmi2FreeFMUstate");
    fmi2Status (*state_size)(fmi2Component, fmi2FMUstate, size_t *) = symbol(library, "fmi2SerializedFMUstateSize");
    fmi2Status (*serialize)(fmi2Component, fmi2FMUstate, char *, size_t) = symbol(library, "fmi2SerializeFMUstate");
    fmi2Status (*deserialize)(fmi2Component, const char *, size_t, fmi2FMUstate *) = symbol(library, "fmi2DeSerializeFMUstate");
    fmi2Status (*terminate)(fmi2Component) = symbol(library, "fmi2Terminate");
    fmi2Status (*new_discrete_states)(fmi2Component, fmi2EventInfo *) = symbol(library, "fmi2NewDiscreteStates");
    fmi2Status (*continuous)(fmi2Component) = symbol(library, "fmi2EnterContinuousTimeMode");
    fmi2Status (*set_time)(fmi2Component, double) = symbol(library, "fmi2SetTime");
    fmi2Status (*get_x)(fmi2Component, double *, size_t) = symbol(library, "fmi2GetContinuousStates");
    fmi2Status (*set_x)(fmi2Component, const double *, size_t) = symbol(library, "fmi2SetContinuousStates");
    fmi2Status (*get_dx)(fmi2Component, double *, size_t) = symbol(library, "fmi2GetDerivatives");
    fmi2Status (*completed)(fmi2Component, int, int *, int *) = symbol(library, "fmi2CompletedIntegratorStep");

    fmi2CallbackFunctions callbacks = {logger, NULL, NULL, NULL, NULL};
    /* Value references 1.. are the Real variables (0 is the Integer `method`). */
    unsigned *vrs = malloc(n_reals * sizeof *vrs);
    double *values = malloc(n_reals * sizeof *values);
    for (size_t k = 0; k < n_reals; k++) vrs[k] = (unsigned)(k + 1);
    double *x = malloc(nx * sizeof *x), *dx = malloc(nx * sizeof *dx);
    const double h = 0.01;

    for (int run = 0; run < runs; run++) {
        fmi2Component c = instantiate("valgrind", fmi2CoSimulation, guid, uri, &callbacks, 0, 0);
        if (!c) {
            fprintf(stderr, "fmi2Instantiate failed\n");
            return 1;
        }
        CHECK(setup(c, 0, 0.0, 0.0, 0, 0.0), fmi2OK);
        CHECK(enter(c), fmi2OK);
        unsigned start_vrs[2] = {vrs[n_reals - 1], 3};  /* the last output is not settable: refused */
        double start[2] = {0.5, 0.25};
        CHECK(set_real(c, &start_vrs[1], 1, &start[1]), fmi2OK);
        CHECK(exit_init(c), fmi2OK);
        fmi2FMUstate saved = NULL, copy = NULL;
        for (int k = 0; k < steps; k++) {
            CHECK(do_step(c, k * h, h, 1), fmi2OK);
            CHECK(get_real(c, vrs, n_reals, values), fmi2OK);
            for (size_t i = 0; i < n_reals; i++) {
                if (!isfinite(values[i])) {
                    fprintf(stderr, "value reference %u = %g after step %d\n", vrs[i], values[i], k);
                    return 1;
                }
            }
            if (k % 100 == 0) {
                CHECK(get_state(c, &saved), fmi2OK); /* the second time it overwrites */
                size_t size = 0;
                CHECK(state_size(c, saved, &size), fmi2OK);
                char *blob = malloc(size);
                CHECK(serialize(c, saved, blob, size), fmi2OK);
                CHECK(deserialize(c, blob, size, &copy), fmi2OK);
                CHECK(deserialize(c, blob, size - 1, &copy), fmi2Error);
                CHECK(set_state(c, copy), fmi2OK);
                free(blob);
                CHECK(free_state(c, &copy), fmi2OK);
            }
        }
        CHECK(set_real(c, start_vrs, 1, start), fmi2Error);
        CHECK(set_state(c, saved), fmi2OK);
        CHECK(terminate(c), fmi2OK);
        if (run % 2 == 0) CHECK(free_state(c, &saved), fmi2OK); /* else fmi2FreeInstance frees it */
        free_instance(c);

        fmi2Component m = instantiate("valgrind-me", fmi2ModelExchange, guid, uri, &callbacks, 0, 0);
        if (!m) {
            fprintf(stderr, "fmi2Instantiate (model exchange) failed\n");
            return 1;
        }
        CHECK(setup(m, 0, 0.0, 0.0, 0, 0.0), fmi2OK);
        CHECK(enter(m), fmi2OK);
        CHECK(set_real(m, &start_vrs[1], 1, &start[1]), fmi2OK);
        CHECK(exit_init(m), fmi2OK);
        fmi2EventInfo info;
        CHECK(new_discrete_states(m, &info), fmi2OK);
        CHECK(continuous(m), fmi2OK);
        CHECK(get_x(m, x, nx), fmi2OK);
        int event = 0, stop = 0;
        for (int k = 0; k < steps; k++) {
            CHECK(set_time(m, k * 1e-4), fmi2OK);
            CHECK(set_x(m, x, nx), fmi2OK);
            CHECK(get_dx(m, dx, nx), fmi2OK);
            for (size_t i = 0; i < nx; i++) {
                if (!isfinite(dx[i])) {
                    fprintf(stderr, "derivative %zu = %g at step %d\n", i, dx[i], k);
                    return 1;
                }
                x[i] += 1e-4 * dx[i];
            }
            CHECK(completed(m, 1, &event, &stop), fmi2OK);
        }
        CHECK(get_dx(m, dx, nx - 1), fmi2Error); /* the wrong count */
        free_instance(m);
    }
    free(vrs);
    free(values);
    free(x);
    free(dx);
    dlclose(library);
    printf("%d runs of %d steps, %d messages logged\n", runs, steps, logged);
    return 0;
}
