/* A seeded fuzz run of the protocol layer, for a build under AddressSanitizer and UBSan.
 *
 *   gcc -std=c99 -Wall -Wextra -Werror -pedantic -g -O1 -fsanitize=address,undefined \
 *       -fno-sanitize-recover=all -I.. -o fuzz-parser fuzz_parser.c ../rovlink_proto.c \
 *       ../rovlink_commands.c
 *   ./fuzz-parser 200000 1        iterations, seed
 *
 * Each iteration feeds a random stream, built from raw bytes, the protocol's characters and
 * whole valid and damaged frames, in random chunks (now and then with bytes lost between two,
 * rl_rx_lost), in either checksum mode. The callbacks
 * check what a controller relies on: commands with in-range values only, replies formatted
 * within their buffer and free of bytes that are not printable, motion only while unlocked.
 * They also give the layer what an app might: debug texts of any bytes and length, numbers
 * of any 32 bits, sensor values far out of their ranges.
 * Any violation (or a sanitizer report) exits non-zero.
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "rovlink_proto.h"

static uint32_t state;
static rl_link link;
static unsigned long commands, replies, output_bytes;

static uint32_t next_random(void) { /* xorshift32 */
    state ^= state << 13;
    state ^= state >> 17;
    state ^= state << 5;
    return state;
}

static void fail(const char *what) {
    fprintf(stderr, "fuzz-parser: %s (seed state %u)\n", what, (unsigned)state);
    exit(1);
}

static void on_write(void *context, const char *data, size_t length) {
    size_t i;
    (void)context;
    output_bytes += length;
    if (length == 0 || length > 96) fail("a write of an odd length");
    for (i = 0; i < length; i++) {
        unsigned char c = (unsigned char)data[i];
        if ((c < 0x20 || c > 0x7e) && c != '\r' && c != '\n') fail("a byte not printable");
    }
    if (data[0] == '$') {
        replies++;
        if (data[length - 1] != '!') fail("a reply that does not end in '!'");
    } else if (memchr(data, '#', length) || memchr(data, '$', length) ||
               memchr(data, '!', length)) {
        fail("debug text with a frame character");
    } else if (length < 2 || data[length - 2] != '\r' || data[length - 1] != '\n' ||
               memchr(data, '\r', length - 2) || memchr(data, '\n', length - 2)) {
        fail("a debug line that is not one line ending in CR LF");
    }
}

/* A text of random bytes (none zero), of random length up to 199. */
static const char *random_text(void) {
    static char text[200];
    size_t length = next_random() % sizeof text, i;
    for (i = 0; i < length; i++) text[i] = (char)(1 + next_random() % 255);
    text[length] = '\0';
    return text;
}

/* What an app writes about a command: any text, any number (debug lines stay whole lines). */
static void app_debug_line(void) {
    const char *before = random_text();
    switch (next_random() % 3) {
    case 0: rl_debug(&link, before); break;
    case 1: rl_debug_flash(&link, before); break;
    default: {
        static char after[200];
        memcpy(after, random_text(), sizeof after);
        rl_debug_number(&link, before, (int32_t)next_random(), (int)(next_random() & 1), after);
    }
    }
}

static void on_command(void *context, rl_command_id command, const int32_t *values) {
    rl_command_spec spec;
    uint8_t i;
    (void)context;
    app_debug_line();
    if ((int)command < 0 || command >= RL_CMD_COUNT) fail("a command id out of range");
    memcpy(&spec, &rl_command_specs[command], sizeof spec);
    for (i = 0; i < spec.argument_count; i++) {
        if (values[i] < spec.arguments[i].minimum || values[i] > spec.arguments[i].maximum) {
            fail("a value out of range reached the app");
        }
    }
    if ((spec.flags & RL_MOTION) && link.locked) fail("motion while locked");
    if (spec.reply_count) fail("a query reached the command callback");
    commands++;
}

static int32_t on_reply(void *context, rl_reply_id reply) {
    rl_reply_spec spec;
    (void)context;
    if ((int)reply < 0 || reply >= RL_REPLY_COUNT) fail("a reply id out of range");
    memcpy(&spec, &rl_reply_specs[reply], sizeof spec);
    /* Extremes of each range, or any 32 bits (the layer writes them within the range). */
    switch (next_random() % 3) {
    case 0: return spec.argument.minimum;
    case 1: return spec.argument.maximum;
    default: return (int32_t)next_random();
    }
}

static const char *const pieces[] = {
    "#", "$", "!", ".", "+", "-", "0", "9", "00000000", "\r\n", " ", "qd", "qsa", "q.l", "crcon",
    "crcoff", "stop", "start", "debug1", "debug0", "mvdirect.1", "mvs.-100", "mvd.9999", "th.360",
    ".100", "mgmp.255", "sdk.10000", "sdz.1024", "h+", "h-", "8C", "ff", "A5", "zz",
    "#qd8C!", "#crcon!", "#crcoff!", "#stop!", "#start!", "#mvs.+50!", "#th.90.100!", "#qsa!",
    "#debug1!", "#mvpdd.7!", "#mvdirect.1!", "#sdz.99999999999!", "#mvs.-2147483648!",
};

static size_t random_stream(uint8_t *out, size_t capacity) {
    size_t length = 0, parts = next_random() % 24, i;
    for (i = 0; i < parts; i++) {
        uint32_t kind = next_random() % 4;
        if (kind == 0) {
            size_t count = next_random() % 8, j;
            for (j = 0; j < count && length < capacity; j++) out[length++] = (uint8_t)next_random();
        } else if (kind == 1 && length + 100 < capacity) {
            size_t count = 60 + next_random() % 20, j; /* around the 64-byte limit */
            out[length++] = '#';
            for (j = 0; j < count; j++) out[length++] = (uint8_t)('0' + next_random() % 10);
            out[length++] = '!';
        } else {
            const char *piece = pieces[next_random() % (sizeof pieces / sizeof pieces[0])];
            size_t size = strlen(piece);
            if (length + size < capacity) {
                memcpy(out + length, piece, size);
                length += size;
            }
        }
    }
    return length;
}

int main(int argc, char **argv) {
    static const rl_app app = {on_write, on_command, on_reply};
    unsigned long iterations = argc > 1 ? strtoul(argv[1], NULL, 10) : 100000ul;
    unsigned long iteration;
    state = argc > 2 ? (uint32_t)strtoul(argv[2], NULL, 10) : 1u;
    if (state == 0) state = 1;
    rl_init(&link, &app, NULL, RL_CRC8);
    for (iteration = 0; iteration < iterations; iteration++) {
        uint8_t stream[1024];
        size_t length = random_stream(stream, sizeof stream), position = 0;
        if (next_random() % 64 == 0) rl_init(&link, &app, NULL, (rl_algorithm)(next_random() % 3));
        while (position < length) {
            size_t chunk = 1 + next_random() % 16;
            if (chunk > length - position) chunk = length - position;
            rl_feed(&link, stream + position, chunk);
            position += chunk;
            if (next_random() % 32 == 0) rl_rx_lost(&link); /* a receive overrun */
            if (link.length > RL_MAX_FRAME_BYTES - 2) fail("the frame buffer overran");
        }
    }
    printf("fuzz-parser: %lu iterations, %lu commands, %lu replies, %lu bytes out: ok\n",
           iterations, commands, replies, output_bytes);
    return 0;
}
