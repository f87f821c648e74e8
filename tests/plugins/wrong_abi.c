/* A plugin built for another major version of the ABI (tests). */
#include <stddef.h>
#include <stdint.h>
uint32_t exoleg_abi_version(void) { return (uint32_t)(2u << 16); }
void *exoleg_create(const void *info) { (void)info; return NULL; }
int32_t exoleg_reset(void *i) { (void)i; return 0; }
int32_t exoleg_step(void *i, const void *r, void *c) { (void)i; (void)r; (void)c; return 0; }
void exoleg_destroy(void *i) { (void)i; }
