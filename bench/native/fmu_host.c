/* A native co-simulation master for timing a nudyn FMU (issue 36): it
 * loads the FMU's library, instantiates it, sets the integer and real
 * parameters and start values given, initializes it, and then, timed,
 * steps it STEPS times by COMM_STEP, reading the value references READ_VRS
 * after every step as a master exchanging data does. That is repeated
 * REPETITIONS times, each run a fresh instance (instantiation and
 * initialization are not timed). It prints one line of JSON: the seconds of
 * each timed loop and, from the last run, every value read (STEPS rows).
 *
 *   fmu_host UNZIPPED_FMU_DIR MODEL_IDENTIFIER GUID COMM_STEP STEPS REPETITIONS READ_VRS [i:VR=VALUE | r:VR=VALUE]...
 *
 * READ_VRS: comma-separated value references. i: sets an Integer (the
 * `method` enumeration), r: a Real (tolerance, theta[k], nu[k], ...), before
 * initialization. Exit status 0 when every call returned fmi2OK or
 * fmi2Warning (a step completed at a tolerance relaxed for round-off, which
 * the logger prints on stderr). */

#include <dlfcn.h>
#include <ctype.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

typedef void *fmi2Component;
typedef int fmi2Status;
typedef struct {
    void (*logger)(void *, const char *, fmi2Status, const char *, const char *, ...);
    void *(*allocateMemory)(size_t, size_t);
    void (*freeMemory)(void *);
    void (*stepFinished)(void *, fmi2Status);
    void *componentEnvironment;
} fmi2CallbackFunctions;

enum { fmi2OK = 0, fmi2Warning = 1, fmi2CoSimulation = 1, MAX_VALUES = 4096, MAX_SETS = 1024 };

static void logger(void *env, const char *name, fmi2Status status, const char *category, const char *message, ...) {
    (void)env, (void)name, (void)category;
    if (status != fmi2OK) fprintf(stderr, "FMU (status %d): %s\n", status, message);
}

static void *symbol(void *library, const char *name) {
    void *f = dlsym(library, name);
    if (!f) {
        fprintf(stderr, "missing symbol %s\n", name);
        exit(2);
    }
    return f;
}

#define CHECK(call)                                                      \
    do {                                                                 \
        fmi2Status status_ = (call);                                     \
        if (status_ > fmi2Warning) {                                     \
            fprintf(stderr, "%s returned status %d\n", #call, status_); \
            exit(1);                                                     \
        }                                                                \
    } while (0)

/* The file URI of DIR/resources/ (an absolute POSIX path), percent-encoded. */
static void resource_uri(const char *dir, char *uri, size_t size) {
    char path[4096];
    snprintf(path, sizeof path, "%s/resources/", dir);
    size_t n = (size_t)snprintf(uri, size, "file://");
    for (const unsigned char *c = (const unsigned char *)path; *c && n + 4 < size; c++) {
        if (isalnum(*c) || strchr("-._~/:", *c)) {
            uri[n++] = (char)*c;
        } else {
            n += (size_t)snprintf(uri + n, size - n, "%%%02X", *c);
        }
    }
    uri[n] = '\0';
}

static double seconds_now(void) {
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

int main(int argc, char **argv) {
    if (argc < 8) {
        fprintf(stderr,
                "usage: %s DIR MODEL_IDENTIFIER GUID COMM_STEP STEPS REPETITIONS READ_VRS [i:VR=V | r:VR=V]...\n",
                argv[0]);
        return 2;
    }
    const char *dir = argv[1], *identifier = argv[2], *guid = argv[3];
    double comm_step = atof(argv[4]);
    long steps = atol(argv[5]), repetitions = atol(argv[6]);
    unsigned read_vrs[MAX_VALUES];
    size_t reads = 0;
    for (char *c = argv[7]; *c && reads < MAX_VALUES; c += *c == ',') read_vrs[reads++] = (unsigned)strtoul(c, &c, 10);
    unsigned int_vrs[MAX_SETS], real_vrs[MAX_SETS];
    int int_values[MAX_SETS];
    double real_values[MAX_SETS];
    size_t ints = 0, reals = 0;
    for (int k = 8; k < argc; k++) {
        char kind = argv[k][0], *rest;
        unsigned vr = (unsigned)strtoul(argv[k] + 2, &rest, 10);
        int malformed = argv[k][1] != ':' || *rest != '=' || (kind != 'i' && kind != 'r');
        if (malformed || ints >= MAX_SETS || reals >= MAX_SETS) {
            fprintf(stderr, "cannot read the setting %s (i:VR=VALUE or r:VR=VALUE)\n", argv[k]);
            return 2;
        }
        if (kind == 'i') {
            int_vrs[ints] = vr, int_values[ints++] = atoi(rest + 1);
        } else {
            real_vrs[reals] = vr, real_values[reals++] = atof(rest + 1);
        }
    }
    if (steps <= 0 || repetitions <= 0 || !(comm_step > 0.0) || reads == 0) {
        fprintf(stderr, "COMM_STEP, STEPS, REPETITIONS and READ_VRS must be positive and given\n");
        return 2;
    }
    char path[4096], uri[8192];
    snprintf(path, sizeof path, "%s/binaries/linux64/%s.so", dir, identifier);
    void *library = dlopen(path, RTLD_NOW | RTLD_LOCAL);
    if (!library) {
        fprintf(stderr, "cannot load %s: %s\n", path, dlerror());
        return 2;
    }
    resource_uri(dir, uri, sizeof uri);
    fmi2Component (*instantiate)(const char *, int, const char *, const char *, const fmi2CallbackFunctions *, int,
                                 int) = symbol(library, "fmi2Instantiate");
    fmi2Status (*setup)(fmi2Component, int, double, double, int, double) = symbol(library, "fmi2SetupExperiment");
    fmi2Status (*enter)(fmi2Component) = symbol(library, "fmi2EnterInitializationMode");
    fmi2Status (*leave)(fmi2Component) = symbol(library, "fmi2ExitInitializationMode");
    fmi2Status (*set_integer)(fmi2Component, const unsigned *, size_t, const int *) = symbol(library, "fmi2SetInteger");
    fmi2Status (*set_real)(fmi2Component, const unsigned *, size_t, const double *) = symbol(library, "fmi2SetReal");
    fmi2Status (*get_real)(fmi2Component, const unsigned *, size_t, double *) = symbol(library, "fmi2GetReal");
    fmi2Status (*do_step)(fmi2Component, double, double, int) = symbol(library, "fmi2DoStep");
    fmi2Status (*terminate)(fmi2Component) = symbol(library, "fmi2Terminate");
    void (*free_instance)(fmi2Component) = symbol(library, "fmi2FreeInstance");
    fmi2CallbackFunctions callbacks = {logger, calloc, free, NULL, NULL};
    double *values = malloc(sizeof(double) * reads * (size_t)steps);
    double *times = malloc(sizeof(double) * (size_t)repetitions);
    if (!values || !times) return 2;
    for (long r = 0; r < repetitions; r++) {
        fmi2Component c = instantiate("host", fmi2CoSimulation, guid, uri, &callbacks, 0, 0);
        if (!c) {
            fprintf(stderr, "fmi2Instantiate failed\n");
            return 1;
        }
        if (ints) CHECK(set_integer(c, int_vrs, ints, int_values));
        if (reals) CHECK(set_real(c, real_vrs, reals, real_values));
        CHECK(setup(c, 0, 0.0, 0.0, 0, 0.0));
        CHECK(enter(c));
        CHECK(leave(c));
        double start = seconds_now();
        for (long n = 0; n < steps; n++) {
            CHECK(do_step(c, (double)n * comm_step, comm_step, 1));
            CHECK(get_real(c, read_vrs, reads, values + (size_t)n * reads));
        }
        times[r] = seconds_now() - start;
        CHECK(terminate(c));
        free_instance(c);
    }
    printf("{\"seconds\": [");
    for (long r = 0; r < repetitions; r++) printf("%s%.9g", r ? ", " : "", times[r]);
    printf("], \"values\": [");
    for (long n = 0; n < steps; n++) {
        printf("%s[", n ? ", " : "");
        for (size_t k = 0; k < reads; k++) printf("%s%.17g", k ? ", " : "", values[(size_t)n * reads + k]);
        printf("]");
    }
    printf("]}\n");
    free(values);
    free(times);
    dlclose(library);
    return 0;
}
