/* A plain C importer of a nudyn FMU, for valgrind and, cross-compiled with
 * mingw, for the win64 binary under wine. RUNS times, one co-simulation
 * instance is instantiated, initialized, stepped STEPS times (setting the
 * inputs, reading every Real value, saving and restoring FMU states, making
 * a refused call), reset, initialized and stepped again (the first step must
 * repeat to the bit), and freed; then a model exchange instance takes STEPS
 * explicit Euler steps through the continuous-state functions, and is
 * freed. NX = 0 means an FMU with neither model exchange nor FMU states
 * (the controller FMU): those parts are left out. Before the runs, a misuse subset: a wrong GUID, a
 * resource location that is not a file URI, calls out of sequence, NULL
 * arrays, an unknown value reference and a NaN input, each refused with a
 * message logged. Under valgrind, the memory still in use at exit must not
 * grow with RUNS, and nothing may be lost.
 *
 *   fmu_runs UNZIPPED_FMU_DIR MODEL_IDENTIFIER GUID N_REALS NX RUNS STEPS [INPUT_VRS [TRACE]]
 *
 * INPUT_VRS: comma-separated value references set before every step to
 * 0.1 sin(t + k) (k the position in the list), or "-" for none. TRACE: a
 * file that receives every Real value after every step of the first run, as
 * native doubles, so two platforms' binaries can be compared.
 *
 * Exit status 0 when every call returned the expected status and every
 * value read was finite. */

#ifdef _WIN32
#include <windows.h>
#else
#include <dlfcn.h>
#endif
#include <ctype.h>
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

enum { fmi2OK = 0, fmi2Discard = 2, fmi2Error = 3, fmi2ModelExchange = 0, fmi2CoSimulation = 1 };

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

#ifdef _WIN32
#define LIBRARY_PATH "%s/binaries/win64/%s.dll"
static void *open_library(const char *path) { return (void *)LoadLibraryA(path); }
static void *symbol_address(void *library, const char *name) { return (void *)GetProcAddress((HMODULE)library, name); }
static void close_library(void *library) { FreeLibrary((HMODULE)library); }
#else
#define LIBRARY_PATH "%s/binaries/linux64/%s.so"
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
        fmi2Status status_ = (call);                                                  \
        if (status_ != (expected)) {                                                  \
            fprintf(stderr, "%s returned %d, expected %d\n", #call, status_, expected); \
            return 1;                                                                 \
        }                                                                             \
    } while (0)

/* A refused call must also say why: at least one message logged. */
#define REFUSED(call, expected)                                                           \
    do {                                                                                  \
        int logged_before_ = logged;                                                      \
        CHECK(call, expected);                                                            \
        if (logged == logged_before_) {                                                   \
            fprintf(stderr, "%s was refused without a message\n", #call);                 \
            return 1;                                                                     \
        }                                                                                 \
    } while (0)

/* A file URI of DIR/resources/: a Windows path (C:\dir) is written
 * file:///C:/dir; everything but unreserved characters, '/' and ':' is
 * percent-encoded (spaces, '%', non-ASCII bytes of UTF-8). */
static void resource_uri(const char *dir, char *uri, size_t size) {
    char path[4096];
    snprintf(path, sizeof path, "%s/resources/", dir);
    size_t n = (size_t)snprintf(uri, size, path[0] == '/' ? "file://" : "file:///");
    for (const unsigned char *c = (const unsigned char *)path; *c && n + 4 < size; c++) {
        unsigned char byte = *c == '\\' ? '/' : *c;
        if (isalnum(byte) || strchr("-._~/:", byte)) {
            uri[n++] = (char)byte;
        } else {
            n += (size_t)snprintf(uri + n, size - n, "%%%02X", byte);
        }
    }
    uri[n] = '\0';
}

/* Value references from "3,4,5" ("-": none); returns how many. */
static size_t parse_vrs(const char *text, unsigned *vrs, size_t capacity) {
    size_t n = 0;
    if (strcmp(text, "-") == 0) return 0;
    for (const char *c = text; *c && n < capacity;) {
        char *end;
        vrs[n++] = (unsigned)strtoul(c, &end, 10);
        c = *end == ',' ? end + 1 : end;
        if (end == c && *end) break;
    }
    return n;
}

int main(int argc, char **argv) {
    if (argc < 8 || argc > 10) {
        fprintf(stderr, "usage: %s UNZIPPED_FMU_DIR MODEL_IDENTIFIER GUID N_REALS NX RUNS STEPS [INPUT_VRS [TRACE]]\n",
                argv[0]);
        return 2;
    }
    const char *dir = argv[1], *identifier = argv[2], *guid = argv[3];
    size_t n_reals = strtoul(argv[4], NULL, 10), nx = strtoul(argv[5], NULL, 10);
    int runs = atoi(argv[6]), steps = atoi(argv[7]);
    unsigned inputs[4096];
    size_t n_inputs = argc > 8 ? parse_vrs(argv[8], inputs, sizeof inputs / sizeof *inputs) : 0;
    FILE *trace = NULL;
    if (argc > 9 && !(trace = fopen(argv[9], "wb"))) {
        fprintf(stderr, "cannot write %s\n", argv[9]);
        return 2;
    }

    char path[4096], uri[4096 * 3];
    snprintf(path, sizeof path, LIBRARY_PATH, dir, identifier);
    resource_uri(dir, uri, sizeof uri);
    void *library = open_library(path);
    if (!library) {
        fprintf(stderr, "cannot load %s\n", path);
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
    fmi2Status (*reset)(fmi2Component) = symbol(library, "fmi2Reset");
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
    double *values = malloc(n_reals * sizeof *values), *first_step = malloc(n_reals * sizeof *first_step);
    double *input_values = malloc((n_inputs + 1) * sizeof *input_values);
    for (size_t k = 0; k < n_reals; k++) vrs[k] = (unsigned)(k + 1);
    double *x = malloc((nx + 1) * sizeof *x), *dx = malloc((nx + 1) * sizeof *dx);
    const double h = 0.01;
    unsigned start_vrs[2] = {vrs[n_reals - 1], 3};  /* the last output is not settable: refused */
    double start[2] = {0.5, 0.25};

    /* The misuse subset: each call refused, with a message. */
    logged = 0;
    if (instantiate("misuse", fmi2CoSimulation, "{not-the-guid}", uri, &callbacks, 0, 0)) {
        fprintf(stderr, "fmi2Instantiate took a wrong GUID\n");
        return 1;
    }
    if (instantiate("misuse", fmi2CoSimulation, guid, "http://example.com/resources/", &callbacks, 0, 0)) {
        fprintf(stderr, "fmi2Instantiate took a resource location that is not a file URI\n");
        return 1;
    }
    if (logged < 2) {
        fprintf(stderr, "refused instantiations logged %d messages, expected 2\n", logged);
        return 1;
    }
    /* After fmi2Error an instance only takes fmi2FreeInstance (and fmi2Reset):
     * each error is the last call of an instance of its own. */
#define FRESH_INSTANCE(c, initialize)                                                \
    fmi2Component c = instantiate("misuse", fmi2CoSimulation, guid, uri, &callbacks, 0, 0); \
    if (!c) {                                                                        \
        fprintf(stderr, "fmi2Instantiate failed\n");                                 \
        return 1;                                                                    \
    }                                                                                \
    if (initialize) {                                                                \
        CHECK(setup(c, 0, 0.0, 0.0, 0, 0.0), fmi2OK);                                \
        CHECK(enter(c), fmi2OK);                                                     \
        CHECK(exit_init(c), fmi2OK);                                                 \
    }
    {
        FRESH_INSTANCE(out_of_sequence, 0)
        REFUSED(exit_init(out_of_sequence), fmi2Error);
        free_instance(out_of_sequence);
    }
    {
        FRESH_INSTANCE(nan_input, 1)
        double nan = NAN;
        if (n_inputs > 0) REFUSED(set_real(nan_input, inputs, 1, &nan), fmi2Discard);
        CHECK(do_step(nan_input, 0.0, h, 1), fmi2OK); /* a discarded input is not taken: stepping goes on */
        REFUSED(get_real(nan_input, vrs, 1, NULL), fmi2Error);
        free_instance(nan_input);
    }
    {
        FRESH_INSTANCE(null_references, 1)
        REFUSED(get_real(null_references, NULL, 1, values), fmi2Error);
        free_instance(null_references);
    }
    {
        FRESH_INSTANCE(unknown_reference, 1)
        unsigned unknown = (unsigned)n_reals + 1000;
        REFUSED(get_real(unknown_reference, &unknown, 1, values), fmi2Error);
        free_instance(unknown_reference);
    }
    {
        FRESH_INSTANCE(wrong_time, 1)
        REFUSED(do_step(wrong_time, 0.5, h, 1), fmi2Error); /* not the current time */
        free_instance(wrong_time);
    }

    for (int run = 0; run < runs; run++) {
        fmi2Component c = instantiate("valgrind", fmi2CoSimulation, guid, uri, &callbacks, 0, 0);
        if (!c) {
            fprintf(stderr, "fmi2Instantiate failed\n");
            return 1;
        }
        CHECK(setup(c, 0, 0.0, 0.0, 0, 0.0), fmi2OK);
        CHECK(enter(c), fmi2OK);
        CHECK(set_real(c, &start_vrs[1], 1, &start[1]), fmi2OK);
        CHECK(exit_init(c), fmi2OK);
        fmi2FMUstate saved = NULL, copy = NULL;
        for (int k = 0; k < steps; k++) {
            for (size_t i = 0; i < n_inputs; i++) input_values[i] = 0.1 * sin(k * h + (double)i);
            CHECK(set_real(c, inputs, n_inputs, input_values), fmi2OK);
            CHECK(do_step(c, k * h, h, 1), fmi2OK);
            CHECK(get_real(c, vrs, n_reals, values), fmi2OK);
            for (size_t i = 0; i < n_reals; i++) {
                if (!isfinite(values[i])) {
                    fprintf(stderr, "value reference %u = %g after step %d\n", vrs[i], values[i], k);
                    return 1;
                }
            }
            if (k == 0) memcpy(first_step, values, n_reals * sizeof *values);
            if (trace && run == 0 && fwrite(values, sizeof *values, n_reals, trace) != n_reals) {
                fprintf(stderr, "cannot write the trace\n");
                return 2;
            }
            if (nx > 0 && k % 100 == 0) {
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
        if (nx > 0) {
            CHECK(set_real(c, start_vrs, 1, start), fmi2Error);
            CHECK(set_state(c, saved), fmi2OK); /* the way out of the error */
            CHECK(terminate(c), fmi2OK);
            if (run % 2 == 0) CHECK(free_state(c, &saved), fmi2OK); /* else fmi2FreeInstance frees it */
        } else {
            CHECK(terminate(c), fmi2OK);
            CHECK(set_real(c, start_vrs, 1, start), fmi2Error); /* fmi2Reset is the way out */
        }

        /* After fmi2Reset the instance starts over: the first step repeats to the bit. */
        CHECK(reset(c), fmi2OK);
        CHECK(setup(c, 0, 0.0, 0.0, 0, 0.0), fmi2OK);
        CHECK(enter(c), fmi2OK);
        CHECK(set_real(c, &start_vrs[1], 1, &start[1]), fmi2OK);
        CHECK(exit_init(c), fmi2OK);
        for (size_t i = 0; i < n_inputs; i++) input_values[i] = 0.1 * sin((double)i);
        CHECK(set_real(c, inputs, n_inputs, input_values), fmi2OK);
        CHECK(do_step(c, 0.0, h, 1), fmi2OK);
        CHECK(get_real(c, vrs, n_reals, values), fmi2OK);
        if (steps > 0 && memcmp(values, first_step, n_reals * sizeof *values) != 0) {
            fprintf(stderr, "the first step after fmi2Reset differs from the first step\n");
            return 1;
        }
        free_instance(c);

        if (nx == 0) continue; /* co-simulation only (the controller FMU) */
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
        if (trace && run == 0 && fwrite(x, sizeof *x, nx, trace) != nx) {
            fprintf(stderr, "cannot write the trace\n");
            return 2;
        }
        CHECK(get_dx(m, dx, nx - 1), fmi2Error); /* the wrong count */
        free_instance(m);
    }
    free(vrs);
    free(values);
    free(first_step);
    free(input_values);
    free(x);
    free(dx);
    if (trace && fclose(trace) != 0) {
        fprintf(stderr, "cannot write the trace\n");
        return 2;
    }
    close_library(library);
    printf("%d runs of %d steps, %d messages logged\n", runs, steps, logged);
    return 0;
}
