/* The Arduino sketch (firmware/c/arduino/rovlink_controller) on a host, driven by a script on
 * stdin, one step a line (arguments N=LEVEL set digital inputs as they are at power-on):
 *
 *   send HEX          bytes to the sketch's serial port
 *   run MS            MS milliseconds of loop(), called every 100 us
 *   clock MS          set the clock to MS ms since power-on (millis() is 32 bits, as on the
 *                     boards: it wraps to 0 after 4294967295, some 49.7 days)
 *   pin N LEVEL       a digital input (a falling edge runs its interrupt)
 *   analog N VALUE    an analog input, 0-1023
 *   hang MS           MS milliseconds without loop(), as a loop stuck in a call (an I2C read
 *                     that never ends): the ESC pulses go on; a watchdog the sketch armed
 *                     and did not reset in time resets the board (setup() again)
 *   show              one line: "at MS pulses P3 P5 P6 P9 P10 P11 claw O C out HEX"
 *                     (the ESC pulses in us, the claw pins, what the sketch wrote since)
 *
 * With --pty (last argument) it serves the sketch on a pseudo-terminal in real time instead
 * (pty_host.cpp), for `rovlink check`.
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "Arduino.h"
#include "Servo.h"

unsigned long host_millis = 0;
static unsigned long host_micros = 0;
int host_pins[PIN_COUNT];
int host_analog[PIN_COUNT];
int host_pulse_us[PIN_COUNT];
static int host_driven[PIN_COUNT]; /* inputs the test drives: a pull-up does not lift them */
static void (*host_handlers[PIN_COUNT])();
HostSerial Serial;
static uint8_t serial_in[4096], serial_out[1 << 16];
static size_t in_start = 0, in_end = 0, out_length = 0;
/* The UART's transmit buffer in a stepped run, as an Uno's core has it: 64 bytes, one of them
 * always free, sent at 10 bits a byte at 115200 baud. */
#define TX_BUFFER_BYTES 63
#define TX_BYTE_US 87
int host_uart_timing = 1;
static size_t tx_queued = 0;
static unsigned long tx_sent_us = 0; /* when the byte at the head of the buffer left */

unsigned long millis() { return host_millis & 0xFFFFFFFFul; }
int digitalRead(uint8_t pin) { return host_pins[pin]; }
/* The claw's H-bridge inputs (the sketch's pins 7 and 8): both HIGH at once, for however short a
 * time, turns on both sides of a bridge of discrete transistors and shorts its supply. */
#define HOST_BRIDGE_PIN_A 7
#define HOST_BRIDGE_PIN_B 8
void digitalWrite(uint8_t pin, int level) {
    host_pins[pin] = level;
    if (host_pins[HOST_BRIDGE_PIN_A] == HIGH && host_pins[HOST_BRIDGE_PIN_B] == HIGH) {
        fprintf(stderr, "sketch_host: both H-bridge inputs HIGH at %lu ms\n", host_millis);
        exit(3);
    }
}
int analogRead(uint8_t pin) { return host_analog[pin]; }
void pinMode(uint8_t pin, int mode) {
    if (mode == INPUT_PULLUP && !host_driven[pin]) host_pins[pin] = HIGH;
}
void attachInterrupt(uint8_t interrupt, void (*handler)(), int mode) {
    if (mode == FALLING) host_handlers[interrupt] = handler;
}
void host_set_pin(uint8_t pin, int level) {
    int was = host_pins[pin];
    host_driven[pin] = 1;
    host_pins[pin] = level;
    if (was == HIGH && level == LOW && host_handlers[pin]) host_handlers[pin]();
}

/* The bytes the line has sent by now leave the buffer. */
static void tx_drain() {
    while (tx_queued && host_micros - tx_sent_us >= TX_BYTE_US) {
        tx_queued--;
        tx_sent_us += TX_BYTE_US;
    }
}

void HostSerial::begin(unsigned long) {}
int HostSerial::availableForWrite() {
    if (!host_uart_timing) return TX_BUFFER_BYTES;
    tx_drain();
    return (int)(TX_BUFFER_BYTES - tx_queued);
}
/* The UART's receive side in a stepped run, as an Uno's core has it: the sent bytes arrive one
 * every 87 us into a 64-byte buffer (63 of it usable); a byte that finds it full is lost. */
#define RX_BUFFER_BYTES 63
static uint8_t rx_buffer[RX_BUFFER_BYTES];
static size_t rx_start = 0, rx_count = 0;
static unsigned long rx_next_us = 0; /* when the next byte on the line arrives */

static void rx_arrive() {
    while (in_start < in_end && host_micros >= rx_next_us) {
        uint8_t byte = serial_in[in_start++];
        if (rx_count < RX_BUFFER_BYTES) rx_buffer[(rx_start + rx_count++) % RX_BUFFER_BYTES] = byte;
        rx_next_us += TX_BYTE_US;
    }
}

int HostSerial::available() {
    if (!host_uart_timing) return (int)(in_end - in_start);
    rx_arrive();
    return (int)rx_count;
}
int HostSerial::read() {
    int byte;
    if (!host_uart_timing) return in_start < in_end ? serial_in[in_start++] : -1;
    rx_arrive();
    if (!rx_count) return -1;
    byte = rx_buffer[rx_start];
    rx_start = (rx_start + 1) % RX_BUFFER_BYTES;
    rx_count--;
    return byte;
}
size_t HostSerial::write(const uint8_t *data, size_t length) {
    size_t i;
    for (i = 0; host_uart_timing && i < length; i++) {
        tx_drain();
        if (tx_queued == TX_BUFFER_BYTES) { /* the core waits for room, the clock running */
            host_micros = tx_sent_us + TX_BYTE_US;
            host_millis = host_micros / 1000;
            tx_drain();
        }
        if (tx_queued++ == 0) tx_sent_us = host_micros;
    }
    if (out_length + length > sizeof serial_out) length = sizeof serial_out - out_length;
    memcpy(serial_out + out_length, data, length);
    out_length += length;
    return length;
}
size_t HostSerial::host_take(uint8_t *out, size_t size) {
    size_t length = out_length < size ? out_length : size;
    memcpy(out, serial_out, length);
    memmove(serial_out, serial_out + length, out_length - length);
    out_length -= length;
    return length;
}
void HostSerial::host_send(const uint8_t *data, size_t length) {
    if (in_start == in_end) {
        in_start = in_end = 0;
        rx_next_us = host_micros + TX_BYTE_US; /* (the line was idle: the first byte's time) */
    }
    if (in_end + length > sizeof serial_in) length = sizeof serial_in - in_end;
    memcpy(serial_in + in_end, data, length);
    in_end += length;
}

/* The chip's watchdog: off, or its timeout and when the sketch last reset it. */
static unsigned long wdt_timeout_us = 0, wdt_reset_us = 0;
void wdt_enable(int timeout) {
    wdt_timeout_us = 15000ul << timeout;
    wdt_reset_us = host_micros;
}
void wdt_reset() { wdt_reset_us = host_micros; }
void wdt_disable() { wdt_timeout_us = 0; }

static int servo_pins[PIN_COUNT], servo_count = 0;
void Servo::attach(int pin) {
    servo_pins[servo_count++] = pin;
    host_pulse_us[pin] = 1500; /* the library's default pulse */
    pin_ = pin;
}
void Servo::writeMicroseconds(int microseconds) { host_pulse_us[pin_] = microseconds; }

#include "rovlink_controller.ino"

/* A reset by the watchdog: the pins and the servo pulses off, setup() again (the sketch's
 * variables keep their values here, where a real reset sets them afresh). */
static void watchdog_reset() {
    size_t i;
    for (i = 0; i < PIN_COUNT; i++) {
        if (!host_driven[i]) host_pins[i] = LOW;
        host_pulse_us[i] = 0;
    }
    servo_count = 0;
    wdt_timeout_us = 0;
    setup();
}

static void show() {
    size_t i;
    printf("at %lu pulses", host_millis);
    for (i = 0; i < (size_t)servo_count; i++) printf(" %d", host_pulse_us[servo_pins[i]]);
    printf(" claw %d %d out ", host_pins[CLAW_OPEN_PIN], host_pins[CLAW_CLOSE_PIN]);
    for (i = 0; i < out_length; i++) printf("%02x", serial_out[i]);
    printf("\n");
    out_length = 0;
}

int main(int argc, char **argv) {
    char line[8192];
    int i;
    for (i = 1; i < argc; i++) { /* N=LEVEL: a digital input as it is at power-on */
        unsigned pin, level;
        if (sscanf(argv[i], "%u=%u", &pin, &level) == 2 && pin < PIN_COUNT) {
            host_driven[pin] = 1;
            host_pins[pin] = (int)level;
        }
    }
    setup();
    if (argc > 1 && strcmp(argv[argc - 1], "--pty") == 0) {
        host_uart_timing = 0;
        return host_serve_pty(loop);
    }
    while (fgets(line, sizeof line, stdin)) {
        char word[16];
        unsigned long a = 0, b = 0;
        if (sscanf(line, "%15s", word) != 1) continue;
        if (strcmp(word, "send") == 0) {
            const char *hex = line + 5;
            uint8_t bytes[4096];
            size_t count = 0;
            unsigned value;
            while (count < sizeof bytes && sscanf(hex, "%2x", &value) == 1) {
                bytes[count++] = (uint8_t)value;
                hex += 2;
            }
            Serial.host_send(bytes, count);
        } else if (strcmp(word, "run") == 0 && sscanf(line, "%*s %lu", &a) == 1) {
            unsigned long steps = a * 10;
            while (steps--) {
                loop();
                host_micros += 100;
                host_millis = host_micros / 1000;
            }
        } else if (strcmp(word, "hang") == 0 && sscanf(line, "%*s %lu", &a) == 1) {
            unsigned long steps = a * 10;
            while (steps--) {
                host_micros += 100;
                host_millis = host_micros / 1000;
                if (wdt_timeout_us && host_micros - wdt_reset_us > wdt_timeout_us) {
                    watchdog_reset();
                }
            }
        } else if (strcmp(word, "clock") == 0 && sscanf(line, "%*s %lu", &a) == 1) {
            host_millis = a;
            host_micros = a * 1000;
            tx_queued = 0; /* (the time jumped: the line has sent it all) */
            rx_next_us = host_micros;
        } else if (strcmp(word, "pin") == 0 && sscanf(line, "%*s %lu %lu", &a, &b) == 2) {
            host_set_pin((uint8_t)a, (int)b);
        } else if (strcmp(word, "analog") == 0 && sscanf(line, "%*s %lu %lu", &a, &b) == 2) {
            host_analog[a] = (int)b;
        } else if (strcmp(word, "show") == 0) {
            show();
        }
        fflush(stdout);
    }
    return 0;
}
