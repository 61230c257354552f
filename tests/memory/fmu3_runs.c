/* A plain C importer of a nudyn FMI 3.0 FMU, for valgrind and, built with
 * mingw, for the x86_64-windows binary under wine: RUNS times, a
 * co-simulation instance is initialized and stepped STEPS times (reading θ
 * and ν, saving, serializing and restoring FMU states, asking the variable
 * dependencies, making refused calls), and a model exchange instance is
 * integrated STEPS explicit Euler steps through the continuous-state
 * functions; both are freed. Under valgrind, the memory still in use at
 * exit must not grow with RUNS, and nothing may be lost.
 *
 *   fmu3_runs UNZIPPED_FMU_DIR MODEL_IDENTIFIER TOKEN THETA_VR NQ NU_VR NV DER_NU_VR RUNS STEPS [TRACE]
 *
 * TRACE: a file that receives θ and ν after every co-simulation step of the
 * first run, then the model exchange states at its end, as native doubles.
 *
 * Exit status 0 when every call returned the expected status and every
 * value read was finite. */

#ifdef _WIN32
#include <windows.h>
#else
#include <dlfcn.h>
#endif
#include <math.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

typedef void *fmi3Instance;
typedef void *fmi3FMUState;
typedef int fmi3Status;
typedef void (*fmi3LogMessageCallback)(void *, fmi3Status, const char *, const char *);

enum { fmi3OK = 0, fmi3Error = 3 };

static int logged;

static void logger(void *env, fmi3Status status, const char *category, const char *message) {
    (void)env, (void)status, (void)category, (void)message;
    logged++;
}

#ifdef _WIN32
#define LIBRARY_PATH "%s/binaries/x86_64-windows/%s.dll"
static void *open_library(const char *path) { return (void *)LoadLibraryA(path); }
static void *symbol_address(void *library, const char *name) { return (void *)GetProcAddress((HMODULE)library, name); }
static void close_library(void *library) { FreeLibrary((HMODULE)library); }
#else
#define LIBRARY_PATH "%s/binaries/x86_64-linux/%s.so"
static void *open_library(const char *path) { return dlopen(path, RTLD_NOW | RTLD_LOCAL); }
static void *symbol_address(void *library, const char *name) { return dlsym(library, name); }
static void close_library(void *library) { dlclose(library); }
#endif

static void *symbol(void *library, const char *name) {
    void *f = symbol_address(library, name);
    if (!f) {
        fprintf(stderr, "missing symbol %s\n", name);
        exit(2);
    }
    return f;
}

#define CHECK(call, expected)                                                         \
    do {                                                                              \
        fmi3Status status_ = (call);                                                  \
        if (status_ != (expected)) {                                                  \
            fprintf(stderr, "%s returned %d, expected %d\n", #call, status_, expected); \
            return 1;                                                                 \
        }                                                                             \
    } while (0)

static int all_finite(const double *values, size_t n, const char *what, int step) {
    for (size_t i = 0; i < n; i++) {
        if (!isfinite(values[i])) {
            fprintf(stderr, "%s[%zu] = %g at step %d\n", what, i, values[i], step);
            return 0;
        }
    }
    return 1;
}

int main(int argc, char **argv) {
    if (argc != 11 && argc != 12) {
        fprintf(stderr, "usage: %s DIR MODEL_IDENTIFIER TOKEN THETA_VR NQ NU_VR NV DER_NU_VR RUNS STEPS [TRACE]\n",
                argv[0]);
        return 2;
    }
    const char *dir = argv[1], *identifier = argv[2], *token = argv[3];
    unsigned theta_vr = (unsigned)atoi(argv[4]), nu_vr = (unsigned)atoi(argv[6]), der_nu_vr = (unsigned)atoi(argv[8]);
    size_t nq = strtoul(argv[5], NULL, 10), nv = strtoul(argv[7], NULL, 10), nx = nq + nv;
    int runs = atoi(argv[9]), steps = atoi(argv[10]);

    char path[4096], resources[4096];
    snprintf(path, sizeof path, LIBRARY_PATH, dir, identifier);
    snprintf(resources, sizeof resources, "%s/resources/", dir);
    void *library = open_library(path);
    if (!library) {
        fprintf(stderr, "cannot load %s\n", path);
        return 2;
    }
    FILE *trace = NULL;
    if (argc == 12 && !(trace = fopen(argv[11], "wb"))) {
        fprintf(stderr, "cannot write %s\n", argv[11]);
        return 2;
    }
    fmi3Instance (*instantiate_cs)(const char *, const char *, const char *, bool, bool, bool, bool, const unsigned *,
                                   size_t, void *, fmi3LogMessageCallback, void *) =
        symbol(library, "fmi3InstantiateCoSimulation");
    fmi3Instance (*instantiate_me)(const char *, const char *, const char *, bool, bool, void *,
                                   fmi3LogMessageCallback) = symbol(library, "fmi3InstantiateModelExchange");
    void (*free_instance)(fmi3Instance) = symbol(library, "fmi3FreeInstance");
    fmi3Status (*enter)(fmi3Instance, bool, double, double, bool, double) =
        symbol(library, "fmi3EnterInitializationMode");
    fmi3Status (*exit_init)(fmi3Instance) = symbol(library, "fmi3ExitInitializationMode");
    fmi3Status (*set_f64)(fmi3Instance, const unsigned *, size_t, const double *, size_t) =
        symbol(library, "fmi3SetFloat64");
    fmi3Status (*get_f64)(fmi3Instance, const unsigned *, size_t, double *, size_t) = symbol(library, "fmi3GetFloat64");
    fmi3Status (*do_step)(fmi3Instance, double, double, bool, bool *, bool *, bool *, double *) =
        symbol(library, "fmi3DoStep");
    fmi3Status (*get_state)(fmi3Instance, fmi3FMUState *) = symbol(library, "fmi3GetFMUState");
    fmi3Status (*set_state)(fmi3Instance, fmi3FMUState) = symbol(library, "fmi3SetFMUState");
    fmi3Status (*free_state)(fmi3Instance, fmi3FMUState *) = symbol(library, "fmi3FreeFMUState");
    fmi3Status (*state_size)(fmi3Instance, fmi3FMUState, size_t *) = symbol(library, "fmi3SerializedFMUStateSize");
    fmi3Status (*serialize)(fmi3Instance, fmi3FMUState, unsigned char *, size_t) =
        symbol(library, "fmi3SerializeFMUState");
    fmi3Status (*deserialize)(fmi3Instance, const unsigned char *, size_t, fmi3FMUState *) =
        symbol(library, "fmi3DeserializeFMUState");
    fmi3Status (*n_dependencies)(fmi3Instance, unsigned, size_t *) =
        symbol(library, "fmi3GetNumberOfVariableDependencies");
    fmi3Status (*dependencies)(fmi3Instance, unsigned, size_t *, unsigned *, size_t *, int *, size_t) =
        symbol(library, "fmi3GetVariableDependencies");
    fmi3Status (*update)(fmi3Instance, bool *, bool *, bool *, bool *, bool *, double *) =
        symbol(library, "fmi3UpdateDiscreteStates");
    fmi3Status (*continuous)(fmi3Instance) = symbol(library, "fmi3EnterContinuousTimeMode");
    fmi3Status (*set_time)(fmi3Instance, double) = symbol(library, "fmi3SetTime");
    fmi3Status (*get_x)(fmi3Instance, double *, size_t) = symbol(library, "fmi3GetContinuousStates");
    fmi3Status (*set_x)(fmi3Instance, const double *, size_t) = symbol(library, "fmi3SetContinuousStates");
    fmi3Status (*get_dx)(fmi3Instance, double *, size_t) = symbol(library, "fmi3GetContinuousStateDerivatives");
    fmi3Status (*terminate)(fmi3Instance) = symbol(library, "fmi3Terminate");

    double *values = malloc(nx * sizeof *values), *x = malloc(nx * sizeof *x), *dx = malloc(nx * sizeof *dx);
    double *nu0 = calloc(nv, sizeof *nu0);
    nu0[nv > 3 ? 3 : 0] = 0.5;
    unsigned state_vrs[2] = {theta_vr, nu_vr};
    const double h = 0.01;

    for (int run = 0; run < runs; run++) {
        fmi3Instance c = instantiate_cs("valgrind", token, resources, false, false, false, false, NULL, 0, NULL,
                                        logger, NULL);
        if (!c) {
            fprintf(stderr, "fmi3InstantiateCoSimulation failed\n");
            return 1;
        }
        CHECK(enter(c, false, 0.0, 0.0, false, 0.0), fmi3OK);
        CHECK(set_f64(c, &nu_vr, 1, nu0, nv), fmi3OK);
        CHECK(exit_init(c), fmi3OK);
        fmi3FMUState saved = NULL, copy = NULL;
        bool event, terminate_now, early;
        double last;
        for (int k = 0; k < steps; k++) {
            CHECK(do_step(c, k * h, h, true, &event, &terminate_now, &early, &last), fmi3OK);
            CHECK(get_f64(c, state_vrs, 2, values, nx), fmi3OK);
            if (!all_finite(values, nx, "theta and nu", k)) return 1;
            if (trace && run == 0 && fwrite(values, sizeof *values, nx, trace) != nx) {
                fprintf(stderr, "cannot write the trace\n");
                return 2;
            }
            if (k % 100 == 0) {
                CHECK(get_state(c, &saved), fmi3OK); /* the second time it overwrites */
                size_t size = 0;
                CHECK(state_size(c, saved, &size), fmi3OK);
                unsigned char *blob = malloc(size);
                CHECK(serialize(c, saved, blob, size), fmi3OK);
                CHECK(deserialize(c, blob, size, &copy), fmi3OK);
                CHECK(deserialize(c, blob, size - 1, &copy), fmi3Error);
                CHECK(set_state(c, copy), fmi3OK);
                free(blob);
                CHECK(free_state(c, &copy), fmi3OK);
                CHECK(get_f64(c, state_vrs, 2, values, nx - 1), fmi3Error); /* nValues short */
                CHECK(set_state(c, saved), fmi3OK);
                /* Huge counts: refused before anything is read or allocated (2^40 once aborted the host). */
                CHECK(get_f64(c, state_vrs, 2, values, (size_t)1 << 40), fmi3Error);
                CHECK(set_state(c, saved), fmi3OK);
                CHECK(get_f64(c, state_vrs, (size_t)1 << 63, values, nx), fmi3Error);
                CHECK(set_state(c, saved), fmi3OK);
            }
        }
        CHECK(terminate(c), fmi3OK);
        if (run % 2 == 0) CHECK(free_state(c, &saved), fmi3OK); /* else fmi3FreeInstance frees it */
        free_instance(c);

        fmi3Instance m = instantiate_me("valgrind-me", token, resources, false, false, NULL, logger);
        if (!m) {
            fprintf(stderr, "fmi3InstantiateModelExchange failed\n");
            return 1;
        }
        CHECK(enter(m, false, 0.0, 0.0, false, 0.0), fmi3OK);
        CHECK(set_f64(m, &nu_vr, 1, nu0, nv), fmi3OK);
        CHECK(exit_init(m), fmi3OK);
        bool flags[5];
        double next;
        CHECK(update(m, &flags[0], &flags[1], &flags[2], &flags[3], &flags[4], &next), fmi3OK);
        CHECK(continuous(m), fmi3OK);
        size_t n = 0;
        CHECK(n_dependencies(m, der_nu_vr, &n), fmi3OK);
        size_t *elements = malloc(n * sizeof *elements), *known_elements = malloc(n * sizeof *known_elements);
        unsigned *knowns = malloc(n * sizeof *knowns);
        int *kinds = malloc(n * sizeof *kinds);
        CHECK(dependencies(m, der_nu_vr, elements, knowns, known_elements, kinds, n), fmi3OK);
        free(elements), free(known_elements), free(knowns), free(kinds);
        CHECK(get_x(m, x, nx), fmi3OK);
        for (int k = 0; k < steps; k++) {
            CHECK(set_time(m, k * 1e-4), fmi3OK);
            CHECK(set_x(m, x, nx), fmi3OK);
            CHECK(get_dx(m, dx, nx), fmi3OK);
            if (!all_finite(dx, nx, "derivatives", k)) return 1;
            for (size_t i = 0; i < nx; i++) x[i] += 1e-4 * dx[i];
        }
        if (trace && run == 0 && fwrite(x, sizeof *x, nx, trace) != nx) {
            fprintf(stderr, "cannot write the trace\n");
            return 2;
        }
        CHECK(get_dx(m, dx, nx - 1), fmi3Error); /* the wrong count */
        free_instance(m);
    }
    free(values), free(x), free(dx), free(nu0);
    if (trace && fclose(trace) != 0) {
        fprintf(stderr, "cannot write the trace\n");
        return 2;
    }
    close_library(library);
    printf("%d runs of %d steps, %d messages logged\n", runs, steps, logged);
    return 0;
}
