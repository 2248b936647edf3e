/* Replay a byte stream through the protocol layer and print what it did, for comparing it with
 * the Python controller (tests/firmware/test_differential.py).
 *
 *   replay CHUNK [ALGORITHM [debug [QD QR QL QRO QPI QHE]]] < stream
 *       one line per command dispatched ("C <id> <values...>") and per reply frame written
 *       ("R <frame>"); ALGORITHM is 0 (crc8, the default), 1 (xor) or 2 (sum8); with "debug",
 *       one line per debug line too ("D <text>", without its "debug: " and CR LF)
 *
 * The sensor values are fixed: by default qd 1020, qr 530, q.l 0, qro -1, qpi 3, qhe 275 (the
 * Python controller's, in tests/firmware/test_differential.py, for a raw reading of 530), or the
 * six values given, as the app hands them to the layer (even out of their ranges).
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "rovlink_proto.h"

static int print_debug = 0;

static void on_write(void *context, const char *data, size_t length) {
    static const char prefix[] = "debug: ";
    (void)context;
    if (length && data[0] == '$') {
        printf("R %.*s\n", (int)length, data);
    } else if (print_debug && length >= sizeof prefix + 1 &&
               memcmp(data, prefix, sizeof prefix - 1) == 0) {
        printf("D %.*s\n", (int)(length - (sizeof prefix - 1) - 2), data + sizeof prefix - 1);
    }
}

static void on_command(void *context, rl_command_id command, const int32_t *values) {
    rl_command_spec spec;
    uint8_t i;
    (void)context;
    memcpy(&spec, &rl_command_specs[command], sizeof spec);
    printf("C %d", (int)command);
    for (i = 0; i < spec.argument_count; i++) printf(" %ld", (long)values[i]);
    printf("\n");
}

static int32_t values[RL_REPLY_COUNT] = {1020, 530, 0, -1, 3, 275};

static int32_t on_reply(void *context, rl_reply_id reply) {
    (void)context;
    return values[reply];
}

int main(int argc, char **argv) {
    static const rl_app app = {on_write, on_command, on_reply};
    static uint8_t stream[1 << 20];
    rl_link link;
    size_t length = fread(stream, 1, sizeof stream, stdin), position = 0;
    size_t chunk = argc > 1 ? (size_t)strtoul(argv[1], NULL, 10) : 1;
    rl_algorithm algorithm = argc > 2 ? (rl_algorithm)strtoul(argv[2], NULL, 10) : RL_CRC8;
    if (chunk == 0) chunk = 1;
    if (algorithm > RL_SUM8) algorithm = RL_CRC8;
    print_debug = argc > 3 && strcmp(argv[3], "debug") == 0;
    if (argc > 3 + RL_REPLY_COUNT) {
        int i;
        for (i = 0; i < RL_REPLY_COUNT; i++) values[i] = (int32_t)strtol(argv[4 + i], NULL, 10);
    }
    rl_init(&link, &app, NULL, algorithm);
    while (position < length) {
        size_t size = length - position < chunk ? length - position : chunk;
        rl_feed(&link, stream + position, size);
        position += size;
    }
    return 0;
}
