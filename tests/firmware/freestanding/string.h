/* The four functions of <string.h> the protocol layer calls, declared as C99 declares them:
 * what a bare-metal C library (newlib, picolibc) or a vendor's SDK provides. The tests build
 * the layer for targets with no C library installed here (tests/firmware/test_cross_targets.py),
 * so that any other library call is an error. */
#ifndef ROVLINK_TEST_FREESTANDING_STRING_H
#define ROVLINK_TEST_FREESTANDING_STRING_H
#include <stddef.h>
void *memcpy(void *restrict destination, const void *restrict source, size_t count);
void *memset(void *destination, int value, size_t count);
int memcmp(const void *left, const void *right, size_t count);
size_t strlen(const char *text);
#endif
