/*
 * A fake Arduino Due joint-controller board for tests: the board side of the stride Arduino
 * link (drivers/arduino-link/SPEC.md) built on the firmware's own C codec, with six simulated
 * brushless joints (PWM duty, direction, brake), their currents, an over-current trip, the
 * board's watchdog, and an MPU-6050 whose raw samples follow a settable tilt.
 */
#ifndef FAKE_DUE_H
#define FAKE_DUE_H

#include <stddef.h>
#include <stdint.h>

typedef struct fake_due fake_due;

typedef struct {
    uint8_t joints;          /* joints driven (at most 8) */
    uint16_t watchdog_ms;    /* commands must come this often */
    uint16_t max_duty;       /* largest duty accepted, 1/10000 */
    uint16_t current_limit_ma;
    uint16_t state_period_ms;
    uint16_t imu_period_ms;
} fake_due_config;

/* The board with cfg, powered up at time t_us. */
fake_due *fake_due_new(const fake_due_config *cfg, uint64_t t_us);
void fake_due_free(fake_due *d);

/* Bytes received from the host at time t_us. */
void fake_due_receive(fake_due *d, const uint8_t *bytes, size_t n, uint64_t t_us);

/* Advances the board to t_us; writes what it sends into out (at most cap bytes; the rest waits
 * for the next call) and returns how many bytes. */
size_t fake_due_poll(fake_due *d, uint64_t t_us, uint8_t *out, size_t cap);

/* Levers: extra current drawn by a joint (a jammed joint), and the board's tilt (rad). */
void fake_due_set_extra_current(fake_due *d, int joint, double ma);
void fake_due_set_tilt(fake_due *d, double roll, double pitch);

/* What the board is doing, for the tests: a joint's applied duty (1/10000) and brake. */
int fake_due_duty(const fake_due *d, int joint);
int fake_due_braked(const fake_due *d, int joint);
double fake_due_position(const fake_due *d, int joint);

#endif
