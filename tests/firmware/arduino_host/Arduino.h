/* The few Arduino core calls the sketch uses, on a host: a clock the test advances, pins the
 * test sets, a serial port whose bytes the test writes and reads. Enough to run the sketch in
 * tests/firmware/test_arduino_sketch.py; not an Arduino emulator. */
#ifndef ARDUINO_HOST_ARDUINO_H
#define ARDUINO_HOST_ARDUINO_H

#include <math.h>
#include <stddef.h>
#include <stdint.h>

#define HIGH 1
#define LOW 0
#define INPUT 0
#define OUTPUT 1
#define INPUT_PULLUP 2
#define FALLING 2
#define A0 14
#define PI 3.14159265358979
#define PIN_COUNT 20
#define SERIAL_RX_BUFFER_SIZE 64 /* as the AVR core has it */
#define ARDUINO_ARCH_AVR 1 /* as the AVR core's build defines it (avr/wdt.h: the stand-in's) */
#define digitalPinToInterrupt(pin) (pin)
#define constrain(value, low, high) ((value) < (low) ? (low) : (value) > (high) ? (high) : (value))

extern unsigned long host_millis;
extern int host_pins[PIN_COUNT];
extern int host_analog[PIN_COUNT];

unsigned long millis();
int digitalRead(uint8_t pin);
void digitalWrite(uint8_t pin, int level);
int analogRead(uint8_t pin);
void pinMode(uint8_t pin, int mode);
void attachInterrupt(uint8_t interrupt, void (*handler)(), int mode);
/* The test's hand on a digital input: a falling edge runs an interrupt attached to it. */
void host_set_pin(uint8_t pin, int level);

class HostSerial {
  public:
    void begin(unsigned long baud);
    int available();
    int read();
    /* As an Uno's core in a stepped run: a 64-byte transmit buffer (63 of it usable) that drains at 115200 baud
     * (87 us a byte) as the clock goes; write() waits, the clock running, until there is room.
     * With --pty the buffer never fills. */
    size_t write(const uint8_t *data, size_t length);
    int availableForWrite();
    /* The test's side: bytes to the sketch, and what the sketch wrote. */
    void host_send(const uint8_t *data, size_t length);
    size_t host_take(uint8_t *out, size_t size);
};

extern HostSerial Serial;
/* 0 with --pty: the transmit buffer is the terminal's, never full. */
extern int host_uart_timing;

/* Serve the sketch on a pseudo-terminal in real time: millis() follows the clock, loop() runs
 * every 100 us, the serial port is the terminal (pty_host.cpp). Prints the terminal's path. */
int host_serve_pty(void (*loop)());

#endif
