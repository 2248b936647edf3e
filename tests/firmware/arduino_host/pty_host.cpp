/* The sketch on a pseudo-terminal in real time (sketch_host --pty): what `rovlink check` and a
 * terminal program open. Apart from the sketch, whose `link` would meet POSIX's link(). */
#include <fcntl.h>
#include <stdio.h>
#include <stdlib.h>
#include <termios.h>
#include <time.h>
#include <unistd.h>

#include "Arduino.h"

static unsigned long elapsed_ms(const struct timespec &start) {
    struct timespec now;
    clock_gettime(CLOCK_MONOTONIC, &now);
    return (unsigned long)((now.tv_sec - start.tv_sec) * 1000L +
                           (now.tv_nsec - start.tv_nsec) / 1000000L);
}

int host_serve_pty(void (*loop)()) {
    struct termios settings;
    struct timespec start;
    int master = posix_openpt(O_RDWR | O_NOCTTY);
    if (master < 0 || grantpt(master) || unlockpt(master)) return 1;
    const char *path = ptsname(master);
    int terminal = open(path, O_RDWR | O_NOCTTY); /* kept open: programs come and go */
    if (terminal < 0 || tcgetattr(terminal, &settings)) return 1;
    cfmakeraw(&settings);
    if (tcsetattr(terminal, TCSANOW, &settings)) return 1;
    fcntl(master, F_SETFL, O_NONBLOCK);
    printf("sketch ready: pty %s\n", path);
    fflush(stdout);
    clock_gettime(CLOCK_MONOTONIC, &start);
    for (;;) {
        uint8_t bytes[256];
        /* No more than a receive buffer short of full holds: the terminal keeps the rest, and
         * the sketch never sees the full buffer that stands for a lost byte on an Uno. */
        int room = SERIAL_RX_BUFFER_SIZE - 2 - Serial.available();
        ssize_t count = room > 0 ? read(master, bytes, (size_t)room) : 0;
        if (count > 0) Serial.host_send(bytes, (size_t)count);
        loop();
        size_t length = Serial.host_take(bytes, sizeof bytes);
        if (length && write(master, bytes, length) < 0) {
            /* nobody reads the terminal: the bytes are lost, as a UART overruns */
        }
        usleep(100);
        host_millis = elapsed_ms(start);
    }
}
