/* The C reference on a host: the protocol layer over a tiny simulated robot on a pseudo-terminal.
 *
 *   gcc -std=c99 -Wall -Wextra -Werror -pedantic -O2 -I.. -o rovlink-host \
 *       host_robot.c ../rovlink_proto.c ../rovlink_commands.c -lm
 *   ./rovlink-host            prints "rovlink-c ready: pty /dev/pts/N"; then
 *   rovlink check /dev/pts/N
 *
 * The robot: heave with buoyancy, thrust and drag, a 10-bit pressure sensor, wave roll and
 * pitch, a turning compass, a leak latch, a depth PID, the link-loss watchdog of P17. Enough for
 * every check of `rovlink check`, motion checks included; it is not the Python simulator.
 */
#define _XOPEN_SOURCE 600
#define _POSIX_C_SOURCE 200809L

#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <poll.h>
#include <signal.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <termios.h>
#include <time.h>
#include <unistd.h>

#include "rovlink_proto.h"

#define TICK_S 0.01
#define WATCHDOG_S 2.0
#define CLAW_PULSE_S 0.05
#define LEAK_PULSE_S 0.1 /* --leak-at wets the probe this long, as rovlink sim --leak-at does */
#define PI 3.14159265358979

typedef struct {
    rl_link link;
    int fd;
    int output_lost; /* a write found no reader: later ones do not wait for one */
    double time_s;
    /* physics */
    double depth_m, heave_m_s, up_thrust_n;
    /* controller state */
    double vertical_percent;
    int holding, target_cm;
    int direction_deg, power_percent, max_pwm;
    int kp, ki, kd;
    double integral, last_depth_cm, speed_cm_s;
    double thrust_percent; /* the vertical output of the last tick, % (+ up) */
    int zero_raw, k;
    int leak_latched;
    double leak_at_s;
    uint32_t frames_seen;
    double last_frame_s;
    int claw;
    double claw_until_s;
} robot;

/* Set by SIGINT and SIGTERM: the main loop ends, and no write waits any more. */
static volatile sig_atomic_t stopping = 0;

/* How long a write waits for room on a line nobody reads before it drops what is left. */
#define WRITE_WAIT_MS 100

/* As a UART: the bytes go out whether or not anyone reads them. A pseudo-terminal that nobody
 * reads fills up instead; the robot waits for room at most WRITE_WAIT_MS, then drops the rest,
 * and drops at once until a write goes through again, so that it never stops (no tick, no
 * failsafe, no input read, no way to stop it) waiting for a reader. */
static void write_all(void *context, const char *data, size_t length) {
    robot *r = (robot *)context;
    while (length && !stopping) {
        ssize_t written = write(r->fd, data, length);
        if (written < 0) {
            struct pollfd room;
            if (errno == EINTR) continue;
            if (errno != EAGAIN || r->output_lost) return;
            room.fd = r->fd;
            room.events = POLLOUT;
            room.revents = 0;
            if (poll(&room, 1, WRITE_WAIT_MS) <= 0) {
                r->output_lost = 1;
                return;
            }
            continue;
        }
        r->output_lost = 0;
        data += written;
        length -= (size_t)written;
    }
}

static int raw_reading(const robot *r) {
    long raw = lround(20.0 + r->depth_m * 50.0);
    return raw < 0 ? 0 : raw > 1023 ? 1023 : (int)raw;
}

static int depth_cm(const robot *r) {
    long depth = (long)floor((double)(raw_reading(r) - r->zero_raw) * r->k / 100.0);
    return depth < 0 ? 0 : depth > 9999 ? 9999 : (int)depth;
}

/* The depth PID starts afresh: no integral, and the speed estimate at rest (the depth of the
 * last tick is the robot's own), so that a hold begins without a derivative kick from the speed
 * of an earlier hold (P10). */
static void reset_pid(robot *r) {
    r->integral = 0.0;
    r->speed_cm_s = 0.0;
}

/* The motion set-points cleared, as #start! leaves them (P7). */
static void clear_set_points(robot *r) {
    r->vertical_percent = 0.0;
    r->holding = 0;
    r->direction_deg = r->power_percent = 0;
    reset_pid(r);
}

/* Every output off, as #stop! and the failsafe leave them (P7, P17). */
static void neutral(robot *r) {
    clear_set_points(r);
    r->claw = 0;
}

/* A debug line (P5) with printf formatting: the host has stdio, the layer does not need it. */
static void debug_line(robot *r, const char *format, ...) {
    char text[80];
    va_list values;
    va_start(values, format);
    vsnprintf(text, sizeof text, format, values);
    va_end(values);
    rl_debug(&r->link, text);
}

/* A depth PID gain: its line names the gain and its old value, as the Python controller's. */
static void set_gain(robot *r, int *gain, const char *label, int32_t value) {
    debug_line(r, "depth PID %s %ld (was %d)", label, (long)value, *gain);
    *gain = (int)value;
}

/* The layer has checked the command and switched its own states (lock, vertical mode); this
 * is the robot's side, with a debug line for every setting it changes (P5). Set-points persist
 * until changed (P11): only stop and an unlocking start clear them. */
static void on_command(void *context, rl_command_id command, const int32_t *values) {
    robot *r = (robot *)context;
    switch (command) {
    case RL_CMD_STOP: neutral(r); break;
    case RL_CMD_START: clear_set_points(r); break; /* only sent when it unlocks */
    case RL_CMD_MVDIRECT: /* only sent when the mode changes */
        r->vertical_percent = 0.0;
        reset_pid(r);
        r->holding = !values[0] && !r->link.locked; /* depth mode while unlocked: hold (P9) */
        if (r->holding) r->target_cm = depth_cm(r);
        break;
    case RL_CMD_MVS:
        r->vertical_percent = values[0];
        debug_line(r, "vertical thrust %+ld %%", (long)values[0]);
        break;
    case RL_CMD_MVD:
        if (!r->holding) reset_pid(r); /* a new target after none: the PID starts afresh */
        r->holding = 1;
        r->target_cm = (int)values[0];
        debug_line(r, "target depth %ld cm", (long)values[0]);
        break;
    case RL_CMD_TH:
        r->direction_deg = (int)(values[0] % 360);
        r->power_percent = (int)values[1];
        debug_line(r, "horizontal %d deg at %d %%", r->direction_deg, r->power_percent);
        break;
    case RL_CMD_MGMP:
        debug_line(r, "max PWM %ld (was %d)", (long)values[0], r->max_pwm);
        r->max_pwm = (int)values[0];
        break;
    case RL_CMD_MVPDP: set_gain(r, &r->kp, "kp", values[0]); break;
    case RL_CMD_MVPDI: set_gain(r, &r->ki, "ki", values[0]); break;
    case RL_CMD_MVPIDD: set_gain(r, &r->kd, "kd", values[0]); break;
    case RL_CMD_SDZ:
        r->zero_raw = (int)values[0];
        debug_line(r, "depth zero %d", r->zero_raw);
        break;
    case RL_CMD_SDK:
        r->k = (int)values[0];
        debug_line(r, "depth coefficient k %d", r->k);
        break;
    case RL_CMD_SLRESET:
        r->leak_latched = 0;
        rl_debug(&r->link, "leak latch reset");
        break;
    case RL_CMD_H_OPEN:
    case RL_CMD_H_CLOSE:
        r->claw = command == RL_CMD_H_OPEN ? 1 : -1;
        r->claw_until_s = r->time_s + CLAW_PULSE_S;
        debug_line(r, "claw %s for %d ms", r->claw > 0 ? "opening" : "closing",
                   (int)lround(CLAW_PULSE_S * 1000.0));
        break;
    default: break;
    }
}

/* Whole degrees, a tie taken up (toward +infinity) as rovlink's controller does: -2.5 gives -2. */
static int attitude_deg(double value) {
    long rounded = lround(floor(value + 0.5));
    return rounded < -90 ? -90 : rounded > 90 ? 90 : (int)rounded;
}

static int32_t on_reply(void *context, rl_reply_id reply) {
    robot *r = (robot *)context;
    double fade = exp(-r->depth_m / 2.0);
    double phase = 2.0 * PI * r->time_s / 5.0;
    switch (reply) {
    case RL_REPLY_QD: return depth_cm(r);
    case RL_REPLY_QR: return raw_reading(r);
    case RL_REPLY_Q_L: return r->leak_latched;
    case RL_REPLY_QRO: return attitude_deg(2.0 * fade * sin(phase));
    case RL_REPLY_QPI: return attitude_deg(1.0 * fade * sin(phase + 1.3));
    case RL_REPLY_QHE: return (int32_t)((long)(r->time_s * 3.0) % 360);
    default: return 0;
    }
}

static void tick(robot *r) {
    double thrust_percent = r->vertical_percent;
    double net_n, depth;
    r->time_s += TICK_S;
    if (r->leak_at_s >= 0 && r->time_s >= r->leak_at_s &&
        r->time_s < r->leak_at_s + LEAK_PULSE_S && !r->leak_latched) {
        r->leak_latched = 1;
        rl_debug(&r->link, "leak detected, action none");
    }
    if (r->link.valid_frames != r->frames_seen) {
        r->frames_seen = r->link.valid_frames;
        r->last_frame_s = r->time_s;
    } else if (!r->link.locked && r->time_s - r->last_frame_s > WATCHDOG_S) {
        neutral(r); /* (before the line, whose write may wait for the line) */
        rl_lock(&r->link, "failsafe: no valid frame for 2 s: motors stopped and locked");
    }
    if (r->claw && r->time_s >= r->claw_until_s) r->claw = 0;
    depth = depth_cm(r);
    if (r->link.locked) {
        thrust_percent = 0.0;
    } else if (r->holding) { /* depth PID, derivative on the measured speed (P10) */
        double error = depth - r->target_cm;
        r->speed_cm_s += ((depth - r->last_depth_cm) / TICK_S - r->speed_cm_s) * TICK_S / 0.5;
        r->integral += r->ki * 0.005 * error * TICK_S;
        if (r->integral > 100) r->integral = 100;
        if (r->integral < -100) r->integral = -100;
        thrust_percent = r->kp * 0.05 * error + r->integral + r->kd * 0.1 * r->speed_cm_s;
        if (thrust_percent > 100) thrust_percent = 100;
        if (thrust_percent < -100) thrust_percent = -100;
    }
    r->last_depth_cm = depth;
    r->thrust_percent = thrust_percent;
    /* Two vertical thrusters of 2.5 kgf, the PWM cap, lag, buoyancy, drag; + up. */
    r->up_thrust_n += (thrust_percent / 100.0 * r->max_pwm / 255.0 * 49.0 - r->up_thrust_n) * 0.1;
    net_n = 2.0 + r->up_thrust_n;
    r->heave_m_s -= (net_n + 50.0 * r->heave_m_s * fabs(r->heave_m_s)) * TICK_S / 20.0;
    r->depth_m += r->heave_m_s * TICK_S;
    if (r->depth_m < 0) {
        r->depth_m = 0;
        if (r->heave_m_s < 0) r->heave_m_s = 0;
    }
}

/* The robot at power-on, at the surface: the controller's defaults (P7, P8, P10, P13). */
static void robot_init(robot *r) {
    static const rl_app app = {write_all, on_command, on_reply};
    memset(r, 0, sizeof *r);
    r->max_pwm = 255;
    r->kp = 40;
    r->ki = 30;
    r->kd = 20;
    r->zero_raw = 20;
    r->k = 200;
    r->leak_at_s = -1.0;
    rl_init(&r->link, &app, r, RL_CRC8);
}

/* Without a main, for a test that steps the robot in simulated time (tests/firmware). */
#ifndef RL_HOST_ROBOT_NO_MAIN

static void on_signal(int signum) {
    (void)signum;
    stopping = 1;
}

static int open_pty(char *path, size_t size, int *slave) {
    struct termios settings;
    int master = posix_openpt(O_RDWR | O_NOCTTY);
    if (master < 0 || grantpt(master) || unlockpt(master)) return -1;
    strncpy(path, ptsname(master), size - 1);
    path[size - 1] = '\0';
    /* The terminal side raw: no echo, no line editing, no CR/LF translation. */
    *slave = open(path, O_RDWR | O_NOCTTY);
    if (*slave < 0 || tcgetattr(*slave, &settings)) return -1;
    settings.c_iflag &= ~(tcflag_t)(IGNBRK | BRKINT | PARMRK | ISTRIP | INLCR | IGNCR | ICRNL | IXON);
    settings.c_oflag &= ~(tcflag_t)OPOST;
    settings.c_lflag &= ~(tcflag_t)(ECHO | ECHONL | ICANON | ISIG | IEXTEN);
    settings.c_cflag &= ~(tcflag_t)(CSIZE | PARENB);
    settings.c_cflag |= CS8;
    if (tcsetattr(*slave, TCSANOW, &settings)) return -1;
    /* Writes that never wait for a reader (write_all); reads only when poll says so. */
    if (fcntl(master, F_SETFL, fcntl(master, F_GETFL) | O_NONBLOCK)) return -1;
    return master;
}

static double now_s(void) {
    struct timespec now;
    clock_gettime(CLOCK_MONOTONIC, &now);
    return (double)now.tv_sec + (double)now.tv_nsec / 1e9;
}

int main(int argc, char **argv) {
    static robot r;
    char path[128];
    int slave = -1, i;
    double next_tick_s;
    robot_init(&r);
    for (i = 1; i < argc; i += 2) { /* a mistyped option is an error, not ignored */
        const char *value = i + 1 < argc ? argv[i + 1] : "";
        char *end;
        if (strcmp(argv[i], "--leak-at") != 0) {
            fprintf(stderr, "rovlink-c: unknown option %s; usage: %s [--leak-at SECONDS]\n",
                    argv[i], argv[0]);
            return 2;
        }
        r.leak_at_s = strtod(value, &end);
        if (end == value || *end != '\0' || !(r.leak_at_s >= 0.0)) {
            fprintf(stderr, "rovlink-c: --leak-at takes seconds, 0 or more, not '%s'\n", value);
            return 2;
        }
    }
    r.fd = open_pty(path, sizeof path, &slave);
    if (r.fd < 0) {
        perror("rovlink-c: cannot open a pseudo-terminal");
        return 1;
    }
    signal(SIGINT, on_signal);
    signal(SIGTERM, on_signal);
    printf("rovlink-c ready: pty %s (link %u bytes of RAM)\n", path, (unsigned)sizeof r.link);
    fflush(stdout);
    next_tick_s = now_s();
    while (!stopping) {
        struct pollfd watch;
        double wait_s = next_tick_s - now_s();
        int ready;
        watch.fd = r.fd;
        watch.events = POLLIN;
        watch.revents = 0;
        ready = poll(&watch, 1, wait_s > 0 ? (int)(wait_s * 1000.0) + 1 : 0);
        if (ready > 0 && (watch.revents & POLLIN)) {
            uint8_t buffer[256];
            ssize_t count = read(r.fd, buffer, sizeof buffer);
            if (count > 0) rl_feed(&r.link, buffer, (size_t)count);
        }
        while (now_s() >= next_tick_s) {
            tick(&r);
            next_tick_s += TICK_S;
        }
    }
    close(slave);
    close(r.fd);
    return 0;
}

#endif /* RL_HOST_ROBOT_NO_MAIN */
