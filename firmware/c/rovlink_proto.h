/* rovlink C99 reference: the controller's protocol layer (PROTOCOL.md P1-P7, P9, P12, P15).
 *
 * Bytes in (rl_feed), commands out (the app's callbacks), replies and debug lines out (the app's
 * write callback). No malloc, no stdio, no float, fixed buffers: one rl_link is 79 bytes of RAM
 * on AVR and the layer has no other RAM of its own; its command table and texts live in flash
 * on AVR. The names, ranges and flags of every command come from rovlink_commands.{h,c},
 * generated from the Python command table.
 *
 *   rl_link link;
 *   rl_init(&link, &app, &robot, RL_CRC8);
 *   for (;;) { n = uart_read(buf); rl_feed(&link, buf, n); robot_tick(&robot); }
 *
 * Where to call it from: every rl_ function from one context, the main loop, one call at a time.
 * The layer is not re-entrant and keeps no lock; its callbacks run inside rl_feed (and write
 * inside rl_lock and rl_debug*), so they must not call rl_feed. A UART receive interrupt only
 * puts the bytes in a queue that the main loop hands to rl_feed; nothing of rl_link is shared
 * with an interrupt, so nothing needs to be volatile (read link.valid_frames in the main loop
 * too: on an 8-bit chip a 32-bit read while an interrupt changes it can be torn). If the queue
 * overflows or the UART reports an overrun, call rl_rx_lost before feeding what came after.
 * Each write call is one whole reply frame (it starts with '$') or one whole debug line (it
 * starts with "debug: ", at most 96 bytes with its CR LF): a board whose write blocks when its
 * transmit buffer is full can leave out debug lines that do not fit and never a reply (the
 * Arduino sketch does). The deepest stack is about 270 bytes on AVR, the callbacks on top.
 *
 * The layer keeps the states the protocol itself gates on: the checksum mode (P3, switched per
 * frame in both directions), debug output (P5), the motor lock (P7) and the vertical mode (P9).
 * Everything else (outputs, the PID, the watchdog of P17, the leak action) is the app's.
 */
#ifndef ROVLINK_PROTO_H
#define ROVLINK_PROTO_H

#include <stddef.h>
#include <stdint.h>

#include "rovlink_commands.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef enum { RL_CRC8, RL_XOR, RL_SUM8 } rl_algorithm;

/* A string literal kept in flash on AVR (PSTR), where a plain literal takes RAM; itself
 * elsewhere. For the *_flash functions: rl_debug_flash(&link, RL_TEXT("leak latch reset")). */
#if defined(__AVR__)
#define RL_TEXT(literal) PSTR(literal)
#else
#define RL_TEXT(literal) (literal)
#endif

typedef struct {
    /* Write bytes to the serial line (replies, debug lines). */
    void (*write)(void *context, const char *data, size_t length);
    /* A command that passed every check and is not a query. stop, start, mvdirect, h+ and h-
     * come here too, after the layer has switched its own state (start only when it unlocks,
     * mvdirect only when it changes the mode). values[] holds the arguments. P5: the layer
     * writes the debug lines of stop, start and mvdirect; for every other command the app
     * writes one (rl_debug, rl_debug_number) saying what changed. */
    void (*command)(void *context, rl_command_id command, const int32_t *values);
    /* The current value of one reply (a sensor). The layer writes a heading modulo 360 (0-359)
     * and any other value clamped to its reply's range (P13, P15). */
    int32_t (*reply_value)(void *context, rl_reply_id reply);
} rl_app;

typedef struct {
    const rl_app *app;
    void *context;
    uint8_t algorithm;
    uint8_t checksum_on;   /* P3: off after reset */
    uint8_t debug_on;      /* P5: off after reset */
    uint8_t locked;        /* P7: locked after reset */
    uint8_t direct_mode;   /* P9: depth mode after reset */
    uint8_t in_frame;      /* inside a frame: start seen, end not yet */
    uint8_t too_long;      /* the frame outgrew the buffer: dropped, its rest skipped */
    uint8_t start;         /* '#' or '$' */
    uint8_t length;        /* bytes of body (and checksum) in buffer */
    char buffer[RL_MAX_FRAME_BYTES - 2];
    uint32_t valid_frames; /* count of valid commands: the app's link-loss watchdog reads it */
} rl_link;

/* The state after reset: locked, depth mode, checksum and debug off. */
void rl_init(rl_link *link, const rl_app *app, void *context, rl_algorithm algorithm);
/* Handle received bytes, any chunking. Replies are written before this returns (P19). */
void rl_feed(rl_link *link, const uint8_t *data, size_t length);
/* Bytes were lost before the ones fed next: a UART overrun or framing error, a receive buffer
 * that overflowed. The unfinished frame is dropped (with a debug line), since its rest may be
 * lost and the next frame's bytes would complete it: "#th.270.25!#th.0.0!" less "5!#th.0."
 * reads "#th.270.20!" while checksum mode is off. Call it before feeding the bytes that came
 * after the loss, from where rl_feed is called. */
void rl_rx_lost(rl_link *link);
/* Lock the motors as #stop! does (for the app's failsafes) and write why as a debug line. The
 * app zeroes its outputs first: the write may wait for a slow line (as the layer tells the app
 * of a #stop! before it writes its line). */
void rl_lock(rl_link *link, const char *why);
/* Write a debug line if debug is on; '#', '$', '!' and bytes that are not printable become '?'
 * (P5); cut at 87 characters. */
void rl_debug(rl_link *link, const char *text);
/* The debug line before, value, after (a sign on positive values too if with_sign), without
 * stdio: rl_debug_number(link, "max PWM ", 200, 0, "") writes "debug: max PWM 200". */
void rl_debug_number(rl_link *link, const char *before, int32_t value, int with_sign,
                     const char *after);
/* The same with every text in flash (RL_TEXT) on AVR, saving their RAM; elsewhere the same as
 * rl_lock, rl_debug and rl_debug_number. */
void rl_lock_flash(rl_link *link, const char *why);
void rl_debug_flash(rl_link *link, const char *text);
void rl_debug_number_flash(rl_link *link, const char *before, int32_t value, int with_sign,
                           const char *after);
/* The checksum of body[0..length) as the algorithm defines it. */
uint8_t rl_checksum(rl_algorithm algorithm, const char *body, size_t length);
/* The longest reply frame rl_format_reply writes, with room to spare. */
#define RL_REPLY_BYTES 24

/* Format the reply frame for one value into out (RL_REPLY_BYTES); returns its length. The
 * value is written as the protocol writes it: a heading modulo 360, anything else clamped to its
 * reply's range. */
size_t rl_format_reply(const rl_link *link, rl_reply_id reply, int32_t value, char *out);

#ifdef __cplusplus
}
#endif

#endif /* ROVLINK_PROTO_H */
