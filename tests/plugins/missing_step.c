/* A plugin without exoleg_step (tests). */
#include <stddef.h>
#include <stdint.h>
uint32_t exoleg_abi_version(void) { return (uint32_t)(1u << 16); }
void *exoleg_create(const void *info) { (void)info; return NULL; }
int32_t exoleg_reset(void *i) { (void)i; return 0; }
void exoleg_destroy(void *i) { (void)i; }
