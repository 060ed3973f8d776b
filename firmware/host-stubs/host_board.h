/*
 * The host side of the Arduino stubs (Arduino.h, Wire.h), implemented by host_board.cpp: what a
 * harness uses to run a sketch on the host as if it were on the board. The harness owns the
 * clock and the far ends of the serial port; it reads the pins the sketch drives; and it is the
 * world the sketch senses: it provides the voltages on the analog inputs and the devices on the
 * I2C bus (the host_world_* functions, which the harness must define).
 *
 * One board per process image: the stubs keep their state in statics, as the board keeps it in
 * its RAM. A harness that wants several boards loads several copies (see drivers/fakes).
 */
#ifndef HOST_BOARD_H
#define HOST_BOARD_H

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

/* Pins 0..HOST_BOARD_PINS-1 (the Due's digital pins, then A0 = 54 ...). */
#define HOST_BOARD_PINS 128
/* Full scale of the analog inputs, V (the Due's 3.3 V reference). */
#define HOST_BOARD_VREF 3.3

/* Powers the board's peripherals up: pins unset, ports closed, resolutions at the Arduino
 * defaults (8-bit PWM, 10-bit ADC), the clock at 0. The harness then calls the sketch's setup(). */
void host_board_reset(void);

/* The clock that millis() and micros() read, µs since power-up. */
void host_board_set_time_us(uint64_t t_us);
uint64_t host_board_time_us(void);

/* The serial port's far end: bytes the host sent (taken as far as there is room; returns how
 * many), and bytes the sketch wrote (at most cap; returns how many). Nothing moves before the
 * sketch calls Serial.begin(). */
size_t host_serial_feed(const uint8_t *bytes, size_t n);
size_t host_serial_take(uint8_t *out, size_t cap);

/* What the sketch does with a pin: its pinMode (-1 when never set), the level it drives when it
 * is an output (0 otherwise), and its PWM duty 0..1 (analogWrite, at the current resolution;
 * a digitalWrite gives 0 or 1). */
int host_pin_mode(uint8_t pin);
int host_pin_level(uint8_t pin);
double host_pin_duty(uint8_t pin);

/* How many analogWrite calls on a pin changed its value (a benchmark counts the commands the
 * sketch acted on by them). */
uint64_t host_pin_pwm_changes(uint8_t pin);

/* Provided by the harness: the voltage on an analog input pin (A0 ...), V. */
double host_world_analog_volts(uint8_t pin);

/* Provided by the harness: an I2C write to the 7-bit address (returns 0 when a device
 * acknowledged, else nonzero), and a read of n bytes from it into out (returns the bytes read,
 * 0 when nothing answers). */
int host_world_i2c_write(uint8_t address, const uint8_t *bytes, size_t n);
size_t host_world_i2c_read(uint8_t address, uint8_t *out, size_t n);

#ifdef __cplusplus
}
#endif

#endif
