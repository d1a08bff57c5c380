/*
 * A fixed-step FMI 2.0 Co-Simulation master loop in C, for timing an FMU
 * through its C ABI with no interpreter in the loop (examples/cabi.py
 * compiles this file and calls hm_run once per simulation through ctypes).
 *
 * hm_run dlopens the FMU's shared library, then (timed with
 * CLOCK_MONOTONIC, from fmi2Instantiate to fmi2FreeInstance inclusive):
 * instantiate, set the parameters (Real, Integer, Boolean), setup the
 * experiment (stop time n_steps * h), initialize with the inputs L[0], u[0],
 * read the outputs, and per step n = 0 .. n_steps - 1:
 *   fmi2SetReal(length, activation = L[n], u[n]);
 *   [fmi2SetRealInputDerivatives(length, activation; order 1; dL[n], du[n])]
 *   fmi2DoStep(n h, h);  fmi2GetReal(outputs) -> out[(n + 1) * n_out ...].
 * These are the calls the fmpy loop of examples/muscle_models.py makes, so the
 * results are identical and the times differ only by the importer.
 *
 * Returns 0, or a negative code with a message in err (the failing call and
 * the FMU's last warning/error message).
 */
#include <dlfcn.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "fmi2FunctionTypes.h"

static char last_message[2048];

static void logger(fmi2ComponentEnvironment env, fmi2String instance, fmi2Status status,
                   fmi2String category, fmi2String message, ...) {
    (void)env; (void)instance; (void)category;
    if (status >= fmi2Warning) {
        va_list args;
        va_start(args, message);
        vsnprintf(last_message, sizeof last_message, message, args);
        va_end(args);
    }
}

typedef struct {
    fmi2InstantiateTYPE *instantiate;
    fmi2FreeInstanceTYPE *free_instance;
    fmi2SetupExperimentTYPE *setup_experiment;
    fmi2EnterInitializationModeTYPE *enter_init;
    fmi2ExitInitializationModeTYPE *exit_init;
    fmi2TerminateTYPE *terminate;
    fmi2SetRealTYPE *set_real;
    fmi2SetIntegerTYPE *set_integer;
    fmi2SetBooleanTYPE *set_boolean;
    fmi2GetRealTYPE *get_real;
    fmi2SetRealInputDerivativesTYPE *set_input_derivatives;
    fmi2DoStepTYPE *do_step;
} Api;

static int load(const char *library, Api *api, char *err, int err_len) {
    void *handle = dlopen(library, RTLD_NOW | RTLD_LOCAL);
    if (!handle) {
        snprintf(err, err_len, "dlopen(%s): %s", library, dlerror());
        return -1;
    }
#define SYM(field, name)                                                       \
    api->field = (void *)dlsym(handle, name);                                  \
    if (!api->field) {                                                         \
        snprintf(err, err_len, "dlsym(%s) failed", name);                     \
        return -1;                                                             \
    }
    SYM(instantiate, "fmi2Instantiate");
    SYM(free_instance, "fmi2FreeInstance");
    SYM(setup_experiment, "fmi2SetupExperiment");
    SYM(enter_init, "fmi2EnterInitializationMode");
    SYM(exit_init, "fmi2ExitInitializationMode");
    SYM(terminate, "fmi2Terminate");
    SYM(set_real, "fmi2SetReal");
    SYM(set_integer, "fmi2SetInteger");
    SYM(set_boolean, "fmi2SetBoolean");
    SYM(get_real, "fmi2GetReal");
    SYM(set_input_derivatives, "fmi2SetRealInputDerivatives");
    SYM(do_step, "fmi2DoStep");
#undef SYM
    return 0;
}

static double now(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return ts.tv_sec + 1e-9 * ts.tv_nsec;
}

#define CHECK(call, what)                                                      \
    if ((call) > fmi2Warning) {                                                \
        snprintf(err, err_len, "%s failed: %s", what, last_message);          \
        rc = -2;                                                               \
        goto done;                                                             \
    }

int hm_run(const char *library, const char *guid, const char *resource_uri,
           int n_real, const unsigned *real_vr, const double *real_value,
           int n_int, const unsigned *int_vr, const int *int_value,
           int n_bool, const unsigned *bool_vr, const int *bool_value,
           unsigned vr_length, unsigned vr_activation, int n_out, const unsigned *out_vr,
           int n_steps, double h, const double *L, const double *u,
           const double *dL, const double *du, int use_derivatives,
           double *out, double *elapsed, char *err, int err_len) {
    Api api;
    int rc = load(library, &api, err, err_len);
    if (rc) return rc;
    last_message[0] = 0;
    fmi2CallbackFunctions callbacks = {logger, calloc, free, NULL, NULL};
    double start = now();
    fmi2Component c = api.instantiate("cabi", fmi2CoSimulation, guid, resource_uri, &callbacks,
                                      fmi2False, fmi2False);
    if (!c) {
        snprintf(err, err_len, "fmi2Instantiate failed: %s", last_message);
        return -3;
    }
    const fmi2ValueReference in_vr[2] = {vr_length, vr_activation};
    const fmi2Integer order[2] = {1, 1};
    fmi2Boolean bools[64];
    if (n_bool > 64) n_bool = 64;
    for (int i = 0; i < n_bool; i++) bools[i] = bool_value[i] ? fmi2True : fmi2False;
    if (n_real) CHECK(api.set_real(c, real_vr, n_real, real_value), "fmi2SetReal(parameters)");
    if (n_int) CHECK(api.set_integer(c, int_vr, n_int, int_value), "fmi2SetInteger(parameters)");
    if (n_bool) CHECK(api.set_boolean(c, bool_vr, n_bool, bools), "fmi2SetBoolean(parameters)");
    CHECK(api.setup_experiment(c, fmi2False, 0.0, 0.0, fmi2True, n_steps * h), "fmi2SetupExperiment");
    CHECK(api.enter_init(c), "fmi2EnterInitializationMode");
    {
        double v[2] = {L[0], u[0]};
        CHECK(api.set_real(c, in_vr, 2, v), "fmi2SetReal(initial inputs)");
    }
    CHECK(api.exit_init(c), "fmi2ExitInitializationMode");
    CHECK(api.get_real(c, out_vr, n_out, out), "fmi2GetReal");
    for (int n = 0; n < n_steps; n++) {
        double v[2] = {L[n], u[n]};
        CHECK(api.set_real(c, in_vr, 2, v), "fmi2SetReal");
        if (use_derivatives) {
            double d[2] = {dL[n], du[n]};
            CHECK(api.set_input_derivatives(c, in_vr, 2, order, d), "fmi2SetRealInputDerivatives");
        }
        CHECK(api.do_step(c, n * h, h, fmi2True), "fmi2DoStep");
        CHECK(api.get_real(c, out_vr, n_out, out + (size_t)(n + 1) * n_out), "fmi2GetReal");
    }
    api.terminate(c);
done:
    api.free_instance(c);
    *elapsed = now() - start;
    return rc;
}
