/* The C reference's host robot (firmware/c/host/host_robot.c) stepped in simulated time, driven
 * by a script on stdin, one step a line:
 *
 *   send HEX      bytes to the robot's serial line
 *   run MS        MS milliseconds of 10 ms ticks
 *   leak-at MS    a leak pulse at MS of simulated time (as the host robot's --leak-at)
 *   show          one line: "at MS thrust PERCENT depth CM locked 0|1 out HEX" (the vertical
 *                 output of the last tick, and what the robot wrote since the last show)
 */
#define RL_HOST_ROBOT_NO_MAIN
#include "host/host_robot.c"

int main(void) {
    static robot r;
    char line[8192];
    int pipe_fds[2];
    robot_init(&r);
    if (pipe(pipe_fds)) return 1;
    fcntl(pipe_fds[0], F_SETFL, O_NONBLOCK);
    r.fd = pipe_fds[1]; /* what the robot writes, read back at each show */
    while (fgets(line, sizeof line, stdin)) {
        unsigned long milliseconds;
        if (strncmp(line, "send ", 5) == 0) {
            const char *hex = line + 5;
            uint8_t bytes[4096];
            size_t count = 0;
            unsigned value;
            while (count < sizeof bytes && sscanf(hex, "%2x", &value) == 1) {
                bytes[count++] = (uint8_t)value;
                hex += 2;
            }
            rl_feed(&r.link, bytes, count);
        } else if (sscanf(line, "leak-at %lu", &milliseconds) == 1) {
            r.leak_at_s = (double)milliseconds / 1000.0;
        } else if (sscanf(line, "run %lu", &milliseconds) == 1) {
            unsigned long ticks = milliseconds / 10;
            while (ticks--) tick(&r);
        } else if (strncmp(line, "show", 4) == 0) {
            uint8_t out[4096];
            ssize_t count, i;
            printf("at %ld thrust %.3f depth %d locked %d out ", lround(r.time_s * 1000.0),
                   r.thrust_percent, depth_cm(&r), (int)r.link.locked);
            while ((count = read(pipe_fds[0], out, sizeof out)) > 0) {
                for (i = 0; i < count; i++) printf("%02x", out[i]);
            }
            printf("\n");
        }
        fflush(stdout);
    }
    return 0;
}
