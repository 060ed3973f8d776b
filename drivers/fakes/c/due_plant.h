/*
 * What an Arduino Due leg board is wired to, simulated: six brushless joints, each a BLD-70
 * driver (PWM speed input, direction, brake) with a current sensor on an analog input, and an
 * MPU-6050 on the I2C bus whose raw samples follow a settable tilt. The plant only reads the
 * pins the firmware drives and answers its inputs (through host_board.h); everything the board
 * decides is the firmware's own (firmware/due/stride_link_due).
 */
#ifndef DUE_PLANT_H
#define DUE_PLANT_H

#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

/* Joints wired to the board. */
#define DUE_PLANT_JOINTS 6

/* The plant's physics. */
typedef struct {
    double speed_at_full_duty;  /* rad/s a joint turns at at full duty */
    double idle_current_ma;     /* a driven joint's current at zero duty */
    double current_per_duty_ma; /* and its rise per unit of duty */
} due_plant_config;

/* Everything at rest, the MPU-6050 just powered up (asleep). */
void due_plant_init(const due_plant_config *cfg);

/* Advances the joints and the sensor by dt seconds under the pins as the firmware set them. */
void due_plant_step(double dt);

/* Levers: extra current drawn by a joint (a jammed joint), mA; the board's tilt, rad. */
void due_plant_set_extra_current(int joint, double ma);
void due_plant_set_tilt(double roll, double pitch);

/* What the joints are doing: the duty the driver sees (1/10000, signed by direction, 0 when
 * braked), whether its brake is on, and its position (rad). */
int due_plant_duty(int joint);
int due_plant_braked(int joint);
double due_plant_position(int joint);

/* How many times the sketch changed a joint's PWM value (0 for a joint out of range). */
uint64_t due_plant_pwm_changes(int joint);

#ifdef __cplusplus
}
#endif

#endif
