// Whether this translation unit is built with AddressSanitizer, under GCC or clang.
#pragma once

#if defined(__SANITIZE_ADDRESS__)
#define CPVS_ADDRESS_SANITIZER 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
#define CPVS_ADDRESS_SANITIZER 1
#endif
#endif
