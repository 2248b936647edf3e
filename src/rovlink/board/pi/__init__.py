"""The Raspberry Pi board (or any Linux board with I²C and GPIO), configured by ``rov.toml``.

:func:`rovlink.board.pi.board.open_pi_board` wires the drivers as the configuration says: a
PCA9685 for the ESCs and the claw, an MS5837 or an analog transducer on an ADS1115 for
pressure, a BNO055 IMU, a leak probe on a GPIO input. Hardware libraries (smbus2, gpiozero,
adafruit-circuitpython-bno055: the ``pi`` extra) load only when a device is opened.
"""
