/* A controller that answers queries as fast as the link allows, for the host benchmarks.
 *
 *   cc -O2 -o fast_controller fast_controller.c && ./fast_controller [PORT]
 *
 * Serves TCP clients on 127.0.0.1:PORT (0 or none: any free port), each in its own process as
 * each would have its own controller, and prints "tcp 127.0.0.1:PORT" once it listens. Answers the queries of PROTOCOL.md (P4, P12: `#qsa!` gets
 * the six sensor replies) with `$qd.N!` counting up, follows `#crcon!`/`#crcoff!` (P3, CRC-8/SMBUS
 * both ways, a frame with a wrong checksum is dropped) and ignores every command that sets
 * something. Plain read/write on the socket, TCP_NODELAY, no threads: the benchmarks time the
 * host, not this.
 */
#include <arpa/inet.h>
#include <signal.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <unistd.h>

static unsigned char crc8(const char *data, size_t length) {
    unsigned char crc = 0;
    for (size_t i = 0; i < length; i++) {
        crc ^= (unsigned char)data[i];
        for (int bit = 0; bit < 8; bit++) crc = (crc & 0x80) ? (unsigned char)((crc << 1) ^ 0x07) : (unsigned char)(crc << 1);
    }
    return crc;
}

static int checksum_on;
static unsigned depth_count;

/* Append one reply frame "$BODY!" (with its checksum in checksum mode) to out. */
static size_t reply(char *out, const char *body) {
    size_t length = strlen(body);
    out[0] = '$';
    memcpy(out + 1, body, length);
    if (checksum_on) {
        length += (size_t)sprintf(out + 1 + length, "%02X", crc8(body, length));
    }
    out[1 + length] = '!';
    return length + 2;
}

/* Handle one frame body (between '#' and '!'); return the bytes of reply written to out. */
static size_t handle(char *body, size_t length, char *out) {
    char text[32];
    if (length == 5 && memcmp(body, "crcon", 5) == 0) { checksum_on = 1; return 0; }
    if (length == 6 && memcmp(body, "crcoff", 6) == 0) { checksum_on = 0; return 0; }
    if (checksum_on) {
        char digits[3];
        if (length < 3) return 0;
        length -= 2;
        snprintf(digits, sizeof digits, "%02X", crc8(body, length));
        if (strncasecmp(digits, body + length, 2) != 0) return 0;  /* dropped, never executed */
    }
    body[length] = '\0';
    if (strcmp(body, "qd") == 0) {
        snprintf(text, sizeof text, "qd.%u", depth_count++ % 10000);
        return reply(out, text);
    }
    if (strcmp(body, "qr") == 0) return reply(out, "qr.102");
    if (strcmp(body, "q.l") == 0) return reply(out, "q.l.0");
    if (strcmp(body, "qro") == 0) return reply(out, "qro.+0");
    if (strcmp(body, "qpi") == 0) return reply(out, "qpi.+0");
    if (strcmp(body, "qhe") == 0) return reply(out, "qhe.90");
    if (strcmp(body, "qsa") == 0) {
        size_t n;
        snprintf(text, sizeof text, "qd.%u", depth_count++ % 10000);
        n = reply(out, text);
        n += reply(out + n, "qr.102");
        n += reply(out + n, "q.l.0");
        n += reply(out + n, "qro.+0");
        n += reply(out + n, "qpi.+0");
        return n + reply(out + n, "qhe.90");
    }
    return 0;  /* a command that sets something: no reply (P4) */
}

static void serve(int fd) {
    char input[4096], output[16384], frame[64];
    size_t frame_length = 0;
    int in_frame = 0;
    ssize_t got;
    while ((got = read(fd, input, sizeof input)) > 0) {
        size_t out_length = 0;
        for (ssize_t i = 0; i < got; i++) {
            char byte = input[i];
            if (byte == '#' || byte == '$') { in_frame = byte == '#'; frame_length = 0; }
            else if (!in_frame) continue;
            else if (byte == '!') {
                in_frame = 0;
                if (out_length + 256 < sizeof output)
                    out_length += handle(frame, frame_length, output + out_length);
            } else if (frame_length < sizeof frame - 1) frame[frame_length++] = byte;
            else in_frame = 0;  /* too long (P1): dropped */
        }
        for (size_t sent = 0; sent < out_length;) {
            ssize_t wrote = write(fd, output + sent, out_length - sent);
            if (wrote <= 0) return;
            sent += (size_t)wrote;
        }
    }
}

int main(int argc, char **argv) {
    int one = 1, server = socket(AF_INET, SOCK_STREAM, 0);
    struct sockaddr_in address = {0};
    socklen_t size = sizeof address;
    address.sin_family = AF_INET;
    address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    address.sin_port = htons((unsigned short)(argc > 1 ? atoi(argv[1]) : 0));
    setsockopt(server, SOL_SOCKET, SO_REUSEADDR, &one, sizeof one);
    if (bind(server, (struct sockaddr *)&address, sizeof address) || listen(server, 4)
        || getsockname(server, (struct sockaddr *)&address, &size)) {
        perror("fast_controller");
        return 1;
    }
    printf("tcp 127.0.0.1:%u\n", ntohs(address.sin_port));
    fflush(stdout);
    signal(SIGCHLD, SIG_IGN);  /* no zombies: nobody waits for a connection's process */
    for (;;) {
        int client = accept(server, NULL, NULL);
        if (client < 0) continue;
        if (fork() == 0) {  /* a fresh controller per connection: checksum mode off (P3) */
            close(server);
            setsockopt(client, IPPROTO_TCP, TCP_NODELAY, &one, sizeof one);
            serve(client);
            _exit(0);
        }
        close(client);
    }
}
