/* The Servo library on a host: each attached output remembers its last pulse width. */
#ifndef ARDUINO_HOST_SERVO_H
#define ARDUINO_HOST_SERVO_H

#include "Arduino.h"

class Servo {
  public:
    void attach(int pin);
    void writeMicroseconds(int microseconds);

  private:
    int pin_ = 0;
};

/* The last pulse written to the servo on each pin, us; 0 for a pin with no servo. */
extern int host_pulse_us[PIN_COUNT];

#endif
