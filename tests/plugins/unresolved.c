/*
 * A plugin that calls a function nothing defines (tests/it/hardening3.rs): it links as a
 * shared library (undefined symbols are allowed there), and exoleg must refuse it when it
 * loads (every symbol resolved at load, RTLD_NOW), naming the symbol, not die with exit 127
 * at its first sample in the middle of a sweep.
 */
#include "exoleg_controller.h"

extern double exoleg_test_no_such_function(double);

uint32_t exoleg_abi_version(void) { return EXOLEG_ABI_VERSION; }
void *exoleg_create(const ExolegInfo *info) { return (void *)info; }
int32_t exoleg_reset(void *instance) { (void)instance; return EXOLEG_OK; }
int32_t exoleg_step(void *instance, const ExolegReadings *y, ExolegCommand *cmd) {
    (void)instance;
    cmd->valve_command = exoleg_test_no_such_function(y->force_n);
    return EXOLEG_OK;
}
void exoleg_destroy(void *instance) { (void)instance; }
