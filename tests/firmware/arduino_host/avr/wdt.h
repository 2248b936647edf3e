/* The AVR watchdog on a host (avr-libc's <avr/wdt.h> when compiled for AVR): a timer the sketch
 * must reset before it runs out, or the board resets (sketch_host.cpp: the step "hang"). */
#ifndef ARDUINO_HOST_AVR_WDT_H
#define ARDUINO_HOST_AVR_WDT_H

#if defined(__AVR__)
#pragma GCC system_header /* (for #include_next under -Wpedantic) */
#include_next <avr/wdt.h>
#else
/* avr-libc's timeouts: 15 ms << n. */
#define WDTO_15MS 0
#define WDTO_250MS 4
#define WDTO_500MS 5
#define WDTO_1S 6
#define WDTO_2S 7

void wdt_enable(int timeout);
void wdt_reset();
void wdt_disable();
#endif

#endif
