/* The protocol layer stepped by a script on stdin, one step a line, for the tests of its calls
 * that a byte stream alone cannot make (tests/firmware/test_c_link_calls.py):
 *
 *   feed HEX     bytes to rl_feed
 *   lost         rl_rx_lost: bytes were lost before the next ones
 *
 * It prints "C <name> <values...>" for each command dispatched, "R <frame>" for each reply and
 * "D <text>" for each debug line. Debug output is on from the start.
 */
#include <stdio.h>
#include <string.h>

#include "rovlink_proto.h"

static rl_link link;

static void on_write(void *context, const char *data, size_t length) {
    (void)context;
    if (length > 9 && memcmp(data, "debug: ", 7) == 0) {
        printf("D %.*s\n", (int)(length - 9), data + 7);
    } else {
        printf("R %.*s\n", (int)length, data);
    }
}

static void on_command(void *context, rl_command_id command, const int32_t *values) {
    rl_command_spec spec;
    size_t i;
    (void)context;
    memcpy(&spec, &rl_command_specs[command], sizeof spec);
    for (i = 0; i < RL_SPELLING_COUNT && rl_spellings[i].command != command; i++) {
    }
    printf("C %s", i < RL_SPELLING_COUNT ? rl_spellings[i].name : "?");
    for (i = 0; i < spec.argument_count; i++) printf(" %ld", (long)values[i]);
    printf("\n");
}

static int32_t on_reply(void *context, rl_reply_id reply) {
    (void)context;
    (void)reply;
    return 0;
}

static const rl_app app = {on_write, on_command, on_reply};

int main(void) {
    char line[4096];
    static const uint8_t debug_on[] = "#debug1!";
    rl_init(&link, &app, NULL, RL_CRC8);
    rl_feed(&link, debug_on, sizeof debug_on - 1);
    while (fgets(line, sizeof line, stdin)) {
        if (strncmp(line, "feed ", 5) == 0) {
            const char *hex = line + 5;
            uint8_t bytes[2048];
            size_t count = 0;
            unsigned value;
            while (count < sizeof bytes && sscanf(hex, "%2x", &value) == 1) {
                bytes[count++] = (uint8_t)value;
                hex += 2;
            }
            rl_feed(&link, bytes, count);
        } else if (strncmp(line, "lost", 4) == 0) {
            rl_rx_lost(&link);
        }
        fflush(stdout);
    }
    return 0;
}
