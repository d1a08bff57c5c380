/*
 * Memory check of an FMU binary through its C ABI (issue 4 §3, "Memory").
 *
 * Built by scripts/memory_check.py, either with -fsanitize=address (whose
 * LeakSanitizer reports every heap block unreachable at exit) or plain for a
 * run under valgrind --leak-check=full. The FMU's shared library is not
 * instrumented; the sanitizer and valgrind intercept malloc/free process-wide,
 * so the Rust allocations (the system allocator) are tracked all the same.
 * The library is never dlclosed, so leak reports keep their symbols.
 *
 * Usage:
 *   memory_cycles LIBRARY GUID RESOURCE_URI VR_LENGTH VR_ACTIVATION VR_FORCE
 *                 CYCLES STATE_CYCLES [LEAK] [VR=INT ...]
 *
 * Instance cycles (CYCLES times), each with a fresh instance:
 *   instantiate, the integer parameters VR=INT (e.g. a small FE mesh),
 *   setup, initialization with inputs, three steps of an activated pull, a
 *   rejected call (NaN length: the error message path), a step the instance
 *   refuses (wrong communication point), get/serialize/deserialize/set/free
 *   of an FMU state, a second state the importer never frees (FMI 2.0
 *   §2.1.8: fmi2FreeInstance reclaims it), reset, re-initialization and one
 *   more step, terminate, free.
 * State cycles (STATE_CYCLES times) on one running instance:
 *   get state, serialized size, serialize, deserialize, set, free both.
 * LEAK = 1 deliberately skips fmi2FreeInstance in every instance cycle, so
 * the FMU's own allocations leak: the check's test that a leak is seen.
 *
 * Prints "cycles ok: N instance, M state, force F" and exits 0, or prints the
 * failing call and exits 1. Leaks are the sanitizer's or valgrind's report.
 */
#include <dlfcn.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi2FunctionTypes.h"

static int messages_seen;

static void logger(fmi2ComponentEnvironment env, fmi2String instance, fmi2Status status,
                   fmi2String category, fmi2String message, ...) {
    (void)env; (void)instance; (void)status; (void)category;
    char text[1024];
    va_list args;
    va_start(args, message);
    vsnprintf(text, sizeof text, message, args);
    va_end(args);
    messages_seen++;
}

typedef struct {
    fmi2InstantiateTYPE *instantiate;
    fmi2FreeInstanceTYPE *free_instance;
    fmi2SetupExperimentTYPE *setup_experiment;
    fmi2EnterInitializationModeTYPE *enter_init;
    fmi2ExitInitializationModeTYPE *exit_init;
    fmi2TerminateTYPE *terminate;
    fmi2ResetTYPE *reset;
    fmi2SetRealTYPE *set_real;
    fmi2SetIntegerTYPE *set_integer;
    fmi2GetRealTYPE *get_real;
    fmi2DoStepTYPE *do_step;
    fmi2GetFMUstateTYPE *get_state;
    fmi2SetFMUstateTYPE *set_state;
    fmi2FreeFMUstateTYPE *free_state;
    fmi2SerializedFMUstateSizeTYPE *state_size;
    fmi2SerializeFMUstateTYPE *serialize;
    fmi2DeSerializeFMUstateTYPE *deserialize;
} Api;

static int load(const char *library, Api *api) {
    void *handle = dlopen(library, RTLD_NOW | RTLD_LOCAL);
    if (!handle) {
        fprintf(stderr, "dlopen(%s): %s\n", library, dlerror());
        return 1;
    }
#define SYM(field, name)                                                       \
    api->field = (void *)dlsym(handle, name);                                  \
    if (!api->field) {                                                         \
        fprintf(stderr, "dlsym(%s) failed\n", name);                          \
        return 1;                                                              \
    }
    SYM(instantiate, "fmi2Instantiate");
    SYM(free_instance, "fmi2FreeInstance");
    SYM(setup_experiment, "fmi2SetupExperiment");
    SYM(enter_init, "fmi2EnterInitializationMode");
    SYM(exit_init, "fmi2ExitInitializationMode");
    SYM(terminate, "fmi2Terminate");
    SYM(reset, "fmi2Reset");
    SYM(set_real, "fmi2SetReal");
    SYM(set_integer, "fmi2SetInteger");
    SYM(get_real, "fmi2GetReal");
    SYM(do_step, "fmi2DoStep");
    SYM(get_state, "fmi2GetFMUstate");
    SYM(set_state, "fmi2SetFMUstate");
    SYM(free_state, "fmi2FreeFMUstate");
    SYM(state_size, "fmi2SerializedFMUstateSize");
    SYM(serialize, "fmi2SerializeFMUstate");
    SYM(deserialize, "fmi2DeSerializeFMUstate");
#undef SYM
    return 0;
}

#define EXPECT(call, want)                                                     \
    do {                                                                       \
        fmi2Status got_ = (call);                                              \
        if (got_ != (want)) {                                                  \
            fprintf(stderr, "cycle %d: %s returned %d, expected %d\n", cycle,  \
                    #call, (int)got_, (int)(want));                            \
            return 1;                                                          \
        }                                                                      \
    } while (0)

typedef struct {
    Api api;
    const char *guid, *resources;
    fmi2ValueReference in_vr[2], force_vr;
    int n_int;
    fmi2ValueReference int_vr[8];
    fmi2Integer int_value[8];
    fmi2CallbackFunctions callbacks;
} Setup;

static double pull_length(int n) { return 0.05 * (1.0 + 0.002 * n); }

/* Enter and leave initialization at L0 with activation 0.5. */
static int initialize(const Setup *s, fmi2Component c, int cycle) {
    const Api *a = &s->api;
    if (s->n_int) EXPECT(a->set_integer(c, s->int_vr, s->n_int, s->int_value), fmi2OK);
    EXPECT(a->setup_experiment(c, fmi2False, 0.0, 0.0, fmi2False, 0.0), fmi2OK);
    EXPECT(a->enter_init(c), fmi2OK);
    double v[2] = {pull_length(0), 0.5};
    EXPECT(a->set_real(c, s->in_vr, 2, v), fmi2OK);
    EXPECT(a->exit_init(c), fmi2OK);
    return 0;
}

static int step(const Setup *s, fmi2Component c, int n, double h, int cycle) {
    double v[2] = {pull_length(n + 1), 0.5};
    EXPECT(s->api.set_real(c, s->in_vr, 2, v), fmi2OK);
    EXPECT(s->api.do_step(c, n * h, h, fmi2True), fmi2OK);
    return 0;
}

/* get, serialize, deserialize, set, free: one round trip of an FMU state. */
static int state_round_trip(const Setup *s, fmi2Component c, int cycle, int keep) {
    const Api *a = &s->api;
    fmi2FMUstate state = NULL, restored = NULL;
    size_t size = 0;
    EXPECT(a->get_state(c, &state), fmi2OK);
    EXPECT(a->state_size(c, state, &size), fmi2OK);
    fmi2Byte *bytes = malloc(size);
    if (!bytes) return 1;
    EXPECT(a->serialize(c, state, bytes, size), fmi2OK);
    EXPECT(a->deserialize(c, bytes, size, &restored), fmi2OK);
    free(bytes);
    EXPECT(a->set_state(c, restored), fmi2OK);
    EXPECT(a->free_state(c, &restored), fmi2OK);
    if (!keep) EXPECT(a->free_state(c, &state), fmi2OK);
    return 0;
}

static int instance_cycle(const Setup *s, int cycle, int leak) {
    const Api *a = &s->api;
    const double h = 1e-3;
    fmi2Component c = a->instantiate("memory", fmi2CoSimulation, s->guid, s->resources,
                                     &s->callbacks, fmi2False, fmi2False);
    if (!c) {
        fprintf(stderr, "cycle %d: fmi2Instantiate failed\n", cycle);
        return 1;
    }
    if (initialize(s, c, cycle)) return 1;
    for (int n = 0; n < 3; n++)
        if (step(s, c, n, h, cycle)) return 1;
    double nan_length = NAN;
    EXPECT(a->set_real(c, &s->in_vr[0], 1, &nan_length), fmi2Error);
    EXPECT(a->do_step(c, 99.0, h, fmi2True), fmi2Error);
    if (state_round_trip(s, c, cycle, 0)) return 1;
    if (state_round_trip(s, c, cycle, 1)) return 1;
    EXPECT(a->reset(c), fmi2OK);
    if (initialize(s, c, cycle)) return 1;
    if (step(s, c, 0, h, cycle)) return 1;
    double force = NAN;
    EXPECT(a->get_real(c, &s->force_vr, 1, &force), fmi2OK);
    if (!isfinite(force)) {
        fprintf(stderr, "cycle %d: force %g\n", cycle, force);
        return 1;
    }
    EXPECT(a->terminate(c), fmi2OK);
    if (!leak) a->free_instance(c);
    return 0;
}

int main(int argc, char **argv) {
    if (argc < 9) {
        fprintf(stderr,
                "usage: %s LIBRARY GUID RESOURCE_URI VR_LENGTH VR_ACTIVATION VR_FORCE CYCLES "
                "STATE_CYCLES [LEAK] [VR=INT ...]\n",
                argv[0]);
        return 2;
    }
    Setup s;
    memset(&s, 0, sizeof s);
    if (load(argv[1], &s.api)) return 1;
    s.guid = argv[2];
    s.resources = argv[3];
    s.in_vr[0] = (fmi2ValueReference)strtoul(argv[4], NULL, 10);
    s.in_vr[1] = (fmi2ValueReference)strtoul(argv[5], NULL, 10);
    s.force_vr = (fmi2ValueReference)strtoul(argv[6], NULL, 10);
    int cycles = atoi(argv[7]), state_cycles = atoi(argv[8]);
    int leak = argc > 9 && strcmp(argv[9], "1") == 0;
    for (int i = 10; i < argc && s.n_int < 8; i++) {
        unsigned vr;
        int value;
        if (sscanf(argv[i], "%u=%d", &vr, &value) != 2) {
            fprintf(stderr, "bad integer parameter %s (want VR=INT)\n", argv[i]);
            return 2;
        }
        s.int_vr[s.n_int] = vr;
        s.int_value[s.n_int++] = value;
    }
    s.callbacks = (fmi2CallbackFunctions){logger, calloc, free, NULL, NULL};

    for (int cycle = 0; cycle < cycles; cycle++)
        if (instance_cycle(&s, cycle, leak)) return 1;

    int cycle = -1;
    fmi2Component c = s.api.instantiate("memory-states", fmi2CoSimulation, s.guid, s.resources,
                                        &s.callbacks, fmi2False, fmi2False);
    if (!c || initialize(&s, c, cycle) || step(&s, c, 0, 1e-3, cycle)) return 1;
    for (cycle = 0; cycle < state_cycles; cycle++)
        if (state_round_trip(&s, c, cycle, 0)) return 1;
    double force = NAN;
    EXPECT(s.api.get_real(c, &s.force_vr, 1, &force), fmi2OK);
    s.api.free_instance(c);
    printf("cycles ok: %d instance, %d state, force %.17g, %d log messages\n", cycles,
           state_cycles, force, messages_seen);
    return 0;
}
