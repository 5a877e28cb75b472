/* The C ABI's header at its old place, for callers who build with -Iinclude from a checkout.
 * The header itself is crates/vps-capi/include/vps.h. */
#include "../crates/vps-capi/include/vps.h"
