/* A starting point for an Arduino controller on the rovlink protocol.
 *
 * Copy rovlink_proto.h, rovlink_proto.c, rovlink_commands.h and rovlink_commands.c from
 * firmware/c/ into this sketch's folder (the Arduino IDE compiles the .c files beside the .ino).
 * The protocol layer does the framing, checksums, the motor lock and the vertical mode; this
 * sketch does the board: the pins below, the ESC outputs, the sensors and the failsafes.
 *
 * Pins (change them to your board): two vertical and four horizontal ESCs on servo pins, the
 * pressure sensor on A0 (10-bit), the leak probe on pin 2 (LOW = wet), the claw's H-bridge on
 * pins 7/8. The ESCs take 1000-2000 us pulses, 1500 us stopped.
 */
#include <Servo.h>
/* The chip's watchdog on the AVR boards (Uno, Nano, Mega), avr-libc's: see setup(). */
#if defined(ARDUINO_ARCH_AVR)
#include <avr/wdt.h>
#define HAS_WATCHDOG 1
#endif

extern "C" {
#include "rovlink_proto.h"
}

static const uint8_t VERTICAL_PINS[2] = {3, 5};
static const uint8_t HORIZONTAL_PINS[4] = {6, 9, 10, 11}; /* front left, front right, rear left, rear right */
static const uint8_t PRESSURE_PIN = A0;
static const uint8_t LEAK_PIN = 2;
static const uint8_t CLAW_OPEN_PIN = 7;
static const uint8_t CLAW_CLOSE_PIN = 8;
/* Times in ms, as millis() gives them: 32 bits, wrapping after 49.7 days; compared by their
 * difference, which the wrap does not upset. */
static const uint32_t TICK_MS = 10;
static const uint32_t WATCHDOG_MS = 2000; /* P17 */
static const uint32_t CLAW_PULSE_MS = 50; /* P16 */

static Servo vertical[2];
static Servo horizontal[4];
static rl_link link;

static struct {
    int vertical_percent;      /* direct mode thrust, + up */
    bool holding;              /* depth mode with a target */
    int target_cm;
    int direction_deg, power_percent;
    int max_pwm;
    int kp, ki, kd;
    float integral, speed_cm_s, last_depth_cm;
    int zero_raw, k;
    volatile bool leak_latched;
    uint32_t frames_seen;
    uint32_t last_frame_ms, claw_until_ms;
    bool claw_running; /* (a flag of its own: any time, 0 too, can end a pulse) */
} robot = {0, false, 0, 0, 0, 255, 40, 30, 20, 0, 0, 0, 20, 200, false, 0, 0, 0, false};

/* Debug lines the transmit buffer had no room for, since the last report of them. */
static uint16_t debug_lines_dropped = 0;
/* Serial.availableForWrite() of an empty transmit buffer on an Uno (the core keeps one of its
 * 64 bytes free). A debug line longer than that (up to 96 bytes) still goes out into an empty
 * buffer: the wait for its rest is at most 3 ms. On a core whose Serial does not implement
 * availableForWrite() (Print's own returns 0), set it to 0: every line then goes out. */
static const int TX_EMPTY_ROOM = 63;

/* A reply (it starts with '$') always goes out, at once (P4, P19). A debug line goes out only
 * if it fits the room left in the transmit buffer (or the buffer is empty), else it is counted
 * and reported later: on an Uno Serial.write() waits for room in the core's 64-byte buffer,
 * which drains at 11.5 bytes a ms at 115200 baud, and debug output (a line for each dropped
 * frame of line noise) would hold up the loop: the ticks, the claw pulse, the link watchdog
 * and the reading of #stop!. */
static void write_serial(void *, const char *data, size_t length) {
    int room = Serial.availableForWrite();
    if (data[0] != '$' && (size_t)room < length && room < TX_EMPTY_ROOM) {
        if (debug_lines_dropped < UINT16_MAX) debug_lines_dropped++;
        return;
    }
    Serial.write(reinterpret_cast<const uint8_t *>(data), length);
}

/* "debug: 65535 debug lines dropped: serial output busy" and CR LF, once there is room. */
static void report_debug_lines_dropped() {
    static const int REPORT_BYTES = 56;
    if (!debug_lines_dropped || Serial.availableForWrite() < REPORT_BYTES) return;
    uint16_t count = debug_lines_dropped;
    debug_lines_dropped = 0;
    rl_debug_number_flash(&link, RL_TEXT(""), count, 0,
                          RL_TEXT(" debug lines dropped: serial output busy"));
}

static int raw_pressure() { return analogRead(PRESSURE_PIN); }

static int depth_cm() {
    long depth = (long)(raw_pressure() - robot.zero_raw) * robot.k / 100; /* P13 */
    return depth < 0 ? 0 : depth > 9999 ? 9999 : (int)depth;
}

/* Thrust in % (+ forward / up) to an ESC pulse, scaled by the PWM cap (P8). */
static void drive(Servo &esc, float percent) {
    float duty = percent / 100.0f * (float)robot.max_pwm / 255.0f;
    esc.writeMicroseconds(1500 + (int)(duty * 500.0f));
}

/* The depth PID starts afresh: no integral, and the speed estimate at rest from the depth now,
 * so that a hold begins without a derivative kick from a stale depth (P10). */
static void reset_pid() {
    robot.integral = 0;
    robot.speed_cm_s = 0;
    robot.last_depth_cm = (float)depth_cm();
}

/* The motion set-points cleared, as #start! leaves them (P7); the outputs follow next tick. */
static void clear_set_points() {
    robot.vertical_percent = 0;
    robot.holding = false;
    robot.direction_deg = robot.power_percent = 0;
    reset_pid();
}

static void all_stop() {
    clear_set_points();
    for (Servo &esc : vertical) drive(esc, 0);
    for (Servo &esc : horizontal) drive(esc, 0);
    robot.claw_running = false;
    digitalWrite(CLAW_OPEN_PIN, LOW);
    digitalWrite(CLAW_CLOSE_PIN, LOW);
}

/* The layer has switched the lock and the vertical mode (start comes only when it unlocks,
 * mvdirect only when the mode changes) and writes their debug lines; every other setting gets
 * its line here (P5). Set-points persist until changed (P11). The layer passes only values within
 * their ranges (-100 to 10000): each fits an int of 16 bits (AVR). */
static void on_command(void *, rl_command_id command, const int32_t *values) {
    switch (command) {
    case RL_CMD_STOP: all_stop(); break;
    case RL_CMD_START: clear_set_points(); break;
    case RL_CMD_MVDIRECT:
        robot.vertical_percent = 0;
        reset_pid();
        robot.holding = !values[0] && !link.locked; /* depth mode while unlocked: hold (P9) */
        if (robot.holding) robot.target_cm = depth_cm();
        break;
    case RL_CMD_MVS:
        robot.vertical_percent = (int)values[0];
        rl_debug_number_flash(&link, RL_TEXT("vertical thrust "), values[0], 1, RL_TEXT(" %"));
        break;
    case RL_CMD_MVD:
        if (!robot.holding) reset_pid(); /* a new target after none: the PID starts afresh */
        robot.holding = true;
        robot.target_cm = (int)values[0];
        rl_debug_number_flash(&link, RL_TEXT("target depth "), values[0], 0, RL_TEXT(" cm"));
        break;
    case RL_CMD_TH:
        robot.direction_deg = (int)(values[0] % 360);
        robot.power_percent = (int)values[1];
        rl_debug_number_flash(&link, RL_TEXT("horizontal direction "), robot.direction_deg, 0,
                              RL_TEXT(" deg"));
        rl_debug_number_flash(&link, RL_TEXT("horizontal power "), values[1], 0, RL_TEXT(" %"));
        break;
    case RL_CMD_MGMP:
        robot.max_pwm = (int)values[0];
        rl_debug_number_flash(&link, RL_TEXT("max PWM "), values[0], 0, RL_TEXT(""));
        break;
    case RL_CMD_MVPDP:
        robot.kp = (int)values[0];
        rl_debug_number_flash(&link, RL_TEXT("depth PID kp "), values[0], 0, RL_TEXT(""));
        break;
    case RL_CMD_MVPDI:
        robot.ki = (int)values[0];
        rl_debug_number_flash(&link, RL_TEXT("depth PID ki "), values[0], 0, RL_TEXT(""));
        break;
    case RL_CMD_MVPIDD:
        robot.kd = (int)values[0];
        rl_debug_number_flash(&link, RL_TEXT("depth PID kd "), values[0], 0, RL_TEXT(""));
        break;
    case RL_CMD_SDZ:
        robot.zero_raw = (int)values[0];
        rl_debug_number_flash(&link, RL_TEXT("depth zero "), values[0], 0, RL_TEXT(""));
        break;
    case RL_CMD_SDK:
        robot.k = (int)values[0];
        rl_debug_number_flash(&link, RL_TEXT("depth coefficient k "), values[0], 0, RL_TEXT(""));
        break;
    case RL_CMD_SLRESET:
        robot.leak_latched = false;
        rl_debug_flash(&link, RL_TEXT("leak latch reset"));
        break;
    case RL_CMD_H_OPEN: case RL_CMD_H_CLOSE: /* (the other input off first: never both on) */
        digitalWrite(command == RL_CMD_H_OPEN ? CLAW_CLOSE_PIN : CLAW_OPEN_PIN, LOW);
        digitalWrite(command == RL_CMD_H_OPEN ? CLAW_OPEN_PIN : CLAW_CLOSE_PIN, HIGH);
        robot.claw_until_ms = (uint32_t)millis() + CLAW_PULSE_MS;
        robot.claw_running = true;
        rl_debug_number_flash(&link,
                              command == RL_CMD_H_OPEN ? RL_TEXT("claw opening for ")
                                                       : RL_TEXT("claw closing for "),
                              (int32_t)CLAW_PULSE_MS, 0, RL_TEXT(" ms"));
        break;
    default: break;
    }
}

static int32_t on_reply(void *, rl_reply_id reply) {
    switch (reply) {
    case RL_REPLY_QD: return depth_cm();
    case RL_REPLY_QR: return raw_pressure();
    case RL_REPLY_Q_L: return robot.leak_latched;
    case RL_REPLY_QRO: return 0;   /* read your IMU here: degrees, -90..+90 */
    case RL_REPLY_QPI: return 0;
    case RL_REPLY_QHE: return 0;   /* 0..359 */
    default: return 0;
    }
}

static void leak_fired() { robot.leak_latched = true; } /* latched however short (P14) */

/* The interrupt sees a pulse shorter than a tick; the level, read at power-on and every tick,
 * sees a probe that was wet before power-on or is still wet after #slreset! (P14). */
static void check_leak_level() {
    if (digitalRead(LEAK_PIN) == LOW) robot.leak_latched = true;
}

static const rl_app app = {write_serial, on_command, on_reply};

void setup() {
    Serial.begin(115200); /* P19 */
    for (uint8_t i = 0; i < 2; i++) vertical[i].attach(VERTICAL_PINS[i]);
    for (uint8_t i = 0; i < 4; i++) horizontal[i].attach(HORIZONTAL_PINS[i]);
    pinMode(LEAK_PIN, INPUT_PULLUP);
    pinMode(CLAW_OPEN_PIN, OUTPUT);
    pinMode(CLAW_CLOSE_PIN, OUTPUT);
    attachInterrupt(digitalPinToInterrupt(LEAK_PIN), leak_fired, FALLING);
    check_leak_level();
    all_stop();
    rl_init(&link, &app, nullptr, RL_CRC8);
#if defined(HAS_WATCHDOG)
    /* A loop stuck in a call (an I2C read that never ends, say) would leave the ESCs on their
     * last pulse, which the Servo library goes on sending from its interrupt, and the link
     * watchdog below never comes: the chip's watchdog resets the board instead, which starts
     * locked, at neutral (P21). The loop resets it each turn; it waits at most a few ms. (On
     * another chip, use its watchdog likewise.) */
    wdt_enable(WDTO_500MS);
#endif
}

/* Serial.available() of a full receive buffer. The AVR core drops a byte that finds its buffer
 * full without a word: a full buffer is all the sketch can see of a loss. (Other cores: set
 * it to yours, or report their overrun events through rl_rx_lost.) */
#if defined(SERIAL_RX_BUFFER_SIZE)
static const int RX_FULL = SERIAL_RX_BUFFER_SIZE - 1;
#else
static const int RX_FULL = 0; /* unknown: not watched */
#endif

/* The received bytes to the layer. Once the receive buffer was full, bytes may have been lost
 * after the ones in it: those are fed, then rl_rx_lost drops the frame they end in, which the
 * bytes after the loss would otherwise complete into another command (P1). */
static void receive() {
    static int before_loss = 0; /* bytes still to feed ahead of a possible loss */
    uint8_t buffer[32];
    size_t count = 0, limit = sizeof buffer;
    int waiting = Serial.available();
    if (!before_loss && RX_FULL && waiting >= RX_FULL) before_loss = waiting;
    if (before_loss && (size_t)before_loss < limit) limit = (size_t)before_loss;
    while (count < limit && Serial.available()) buffer[count++] = (uint8_t)Serial.read();
    if (count) rl_feed(&link, buffer, count); /* replies go out before this returns (P19) */
    if (before_loss) {
        before_loss -= (int)count;
        if (!before_loss) rl_rx_lost(&link);
    }
}

void loop() {
    static uint32_t next_tick_ms = 0;
#if defined(HAS_WATCHDOG)
    wdt_reset();
#endif
    receive();

    uint32_t now = (uint32_t)millis();
    if ((int32_t)(now - next_tick_ms) < 0) return;
    next_tick_ms = now + TICK_MS;
    check_leak_level();
    report_debug_lines_dropped();
    if (link.valid_frames != robot.frames_seen) {
        robot.frames_seen = link.valid_frames;
        robot.last_frame_ms = now;
    } else if (!link.locked && now - robot.last_frame_ms > WATCHDOG_MS) { /* P17 */
        all_stop(); /* (before the line, whose write may wait for the line) */
        rl_lock_flash(&link, RL_TEXT("failsafe: no valid frame for 2 s: motors stopped and locked"));
    }
    if (robot.claw_running && (int32_t)(now - robot.claw_until_ms) >= 0) {
        robot.claw_running = false;
        digitalWrite(CLAW_OPEN_PIN, LOW);
        digitalWrite(CLAW_CLOSE_PIN, LOW);
    }
    if (link.locked) return;

    /* Vertical: direct thrust, or the depth PID (P9, P10). */
    float up = (float)robot.vertical_percent;
    if (robot.holding) {
        float depth = (float)depth_cm();
        float error = depth - (float)robot.target_cm; /* too deep: positive: thrust up */
        float dt = TICK_MS / 1000.0f;
        robot.speed_cm_s += ((depth - robot.last_depth_cm) / dt - robot.speed_cm_s) * dt / 0.5f;
        robot.last_depth_cm = depth;
        robot.integral = constrain(robot.integral + (float)robot.ki * 0.005f * error * dt, -100.0f, 100.0f);
        up = constrain((float)robot.kp * 0.05f * error + robot.integral +
                           (float)robot.kd * 0.1f * robot.speed_cm_s,
                       -100.0f, 100.0f);
    }
    for (Servo &esc : vertical) drive(esc, up);

    /* Horizontal: four thrusters at 45 degrees (P11), normalised to 100 %. */
    float angle = (float)robot.direction_deg * (float)PI / 180.0f;
    float power = (float)robot.power_percent;
    float surge = (float)cos(angle) * power, sway = (float)sin(angle) * power;
    float outputs[4] = {surge + sway, surge - sway, surge - sway, surge + sway};
    float largest = 0;
    for (float value : outputs) if (fabsf(value) > largest) largest = fabsf(value);
    float scale = largest > power && largest > 0 ? power / largest : 1;
    for (uint8_t i = 0; i < 4; i++) drive(horizontal[i], outputs[i] * scale);
}
