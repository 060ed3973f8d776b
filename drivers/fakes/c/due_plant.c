/* The plant behind an Arduino Due leg board: see due_plant.h. */
#include "due_plant.h"

#include <math.h>
#include <string.h>

#include "host_board.h"

/* The board's wiring (the firmware's pin map must match it): per joint the driver's PWM input,
 * direction and brake, and the current sensor's analog input (A0 = 54 ...). */
static const unsigned char PWM_PIN[DUE_PLANT_JOINTS] = {2, 3, 4, 5, 6, 7};
static const unsigned char DIR_PIN[DUE_PLANT_JOINTS] = {22, 24, 26, 28, 30, 32};
static const unsigned char BRAKE_PIN[DUE_PLANT_JOINTS] = {23, 25, 27, 29, 31, 33};
static const unsigned char CURRENT_PIN[DUE_PLANT_JOINTS] = {54, 55, 56, 57, 58, 59};
/* The current sensors (ACS711-style): 2.5 A per volt, from 0 V. */
#define AMPS_PER_VOLT 2.5

/* The MPU-6050, AD0 low. */
#define MPU_ADDRESS 0x68
#define MPU_SMPLRT_DIV 0x19
#define MPU_CONFIG 0x1A
#define MPU_GYRO_CONFIG 0x1B
#define MPU_ACCEL_CONFIG 0x1C
#define MPU_DATA 0x3B /* ACCEL_XOUT_H .. GYRO_ZOUT_L, 14 bytes, big-endian */
#define MPU_PWR_MGMT_1 0x6B
#define MPU_PWR_MGMT_2 0x6C
#define MPU_WHO_AM_I 0x75

typedef struct {
    double position, velocity, current_ma, extra_ma;
} joint;

static struct {
    due_plant_config cfg;
    joint j[DUE_PLANT_JOINTS];
    double roll, pitch;
    unsigned int noise;
    unsigned char mpu[128]; /* the MPU-6050's registers */
    unsigned char mpu_at;   /* its register pointer */
} plant;

static void mpu_reset(void) {
    memset(plant.mpu, 0, sizeof plant.mpu);
    plant.mpu[MPU_PWR_MGMT_1] = 0x40; /* asleep */
    plant.mpu[MPU_WHO_AM_I] = MPU_ADDRESS;
    plant.mpu_at = 0;
}

void due_plant_init(const due_plant_config *cfg) {
    memset(&plant, 0, sizeof plant);
    plant.cfg = *cfg;
    plant.noise = 12345;
    mpu_reset();
}

/* The driver's speed input as it sees it: signed duty -1..1. */
static double duty_of(int i) {
    double d = host_pin_duty(PWM_PIN[i]);
    return host_pin_level(DIR_PIN[i]) ? -d : d;
}

uint64_t due_plant_pwm_changes(int joint_index) {
    return joint_index >= 0 && joint_index < DUE_PLANT_JOINTS ? host_pin_pwm_changes(PWM_PIN[joint_index]) : 0;
}

int due_plant_braked(int joint_index) {
    return joint_index >= 0 && joint_index < DUE_PLANT_JOINTS && host_pin_level(BRAKE_PIN[joint_index]);
}

int due_plant_duty(int joint_index) {
    if (joint_index < 0 || joint_index >= DUE_PLANT_JOINTS || due_plant_braked(joint_index)) {
        return 0;
    }
    return (int)lround(duty_of(joint_index) * 10000);
}

double due_plant_position(int joint_index) {
    return joint_index >= 0 && joint_index < DUE_PLANT_JOINTS ? plant.j[joint_index].position : 0;
}

void due_plant_set_extra_current(int joint_index, double ma) {
    if (joint_index >= 0 && joint_index < DUE_PLANT_JOINTS) {
        plant.j[joint_index].extra_ma = ma;
    }
}

void due_plant_set_tilt(double roll, double pitch) {
    plant.roll = roll;
    plant.pitch = pitch;
}

/* A small deterministic noise in [-1, 1]. */
static double noise(void) {
    plant.noise = plant.noise * 1103515245u + 12345u;
    return ((plant.noise >> 16) & 0x7fff) / 16383.5 - 1.0;
}

static void put_word(int reg, double v) {
    long r = lround(v);
    if (r > 32767) r = 32767;
    if (r < -32768) r = -32768;
    plant.mpu[reg] = (unsigned char)(((unsigned long)r >> 8) & 0xff);
    plant.mpu[reg + 1] = (unsigned char)((unsigned long)r & 0xff);
}

/* A new sample into the data registers, at the configured full scales. */
static void mpu_sample(void) {
    double g = 16384.0 / (1 << ((plant.mpu[MPU_ACCEL_CONFIG] >> 3) & 3)); /* counts per g */
    double dps = 131.0 / (1 << ((plant.mpu[MPU_GYRO_CONFIG] >> 3) & 3));  /* per deg/s */
    put_word(MPU_DATA + 0, -sin(plant.pitch) * g + 40 * noise());
    put_word(MPU_DATA + 2, sin(plant.roll) * cos(plant.pitch) * g + 40 * noise());
    put_word(MPU_DATA + 4, cos(plant.roll) * cos(plant.pitch) * g + 40 * noise());
    put_word(MPU_DATA + 6, (30.0 - 36.53) * 340.0); /* 30 °C */
    put_word(MPU_DATA + 8, 0.3 * dps + 5 * noise()); /* a small gyro bias */
    put_word(MPU_DATA + 10, -0.2 * dps + 5 * noise());
    put_word(MPU_DATA + 12, 5 * noise());
}

void due_plant_step(double dt) {
    for (int i = 0; i < DUE_PLANT_JOINTS; i++) {
        joint *j = &plant.j[i];
        int braked = due_plant_braked(i);
        double duty = braked ? 0 : duty_of(i);
        double tau, v_target = 0;
        if (braked) {
            tau = 0.005;
        } else if (duty == 0) {
            tau = 0.5; /* not driven: the joint coasts down */
        } else {
            v_target = plant.cfg.speed_at_full_duty * duty;
            tau = 0.05;
        }
        j->velocity += (v_target - j->velocity) * (1.0 - exp(-dt / tau));
        j->position += j->velocity * dt;
        j->current_ma =
            (braked ? 0 : plant.cfg.idle_current_ma + plant.cfg.current_per_duty_ma * fabs(duty)) +
            j->extra_ma;
    }
    if (!(plant.mpu[MPU_PWR_MGMT_1] & 0x40)) {
        mpu_sample(); /* awake: a sample each step (the 1 kHz accelerometer rate at 1 ms steps) */
    }
}

double host_world_analog_volts(uint8_t pin) {
    for (int i = 0; i < DUE_PLANT_JOINTS; i++) {
        if (pin == CURRENT_PIN[i]) {
            return plant.j[i].current_ma / 1000.0 / AMPS_PER_VOLT;
        }
    }
    return 0;
}

int host_world_i2c_write(uint8_t address, const uint8_t *bytes, size_t n) {
    if (address != MPU_ADDRESS) {
        return 2;
    }
    if (n == 0) {
        return 0;
    }
    plant.mpu_at = bytes[0] & 0x7f;
    for (size_t k = 1; k < n; k++) {
        int reg = plant.mpu_at;
        plant.mpu_at = (plant.mpu_at + 1) & 0x7f;
        if (reg == MPU_PWR_MGMT_1 && (bytes[k] & 0x80)) {
            mpu_reset(); /* DEVICE_RESET */
        } else if (reg == MPU_SMPLRT_DIV || reg == MPU_CONFIG || reg == MPU_GYRO_CONFIG ||
                   reg == MPU_ACCEL_CONFIG || reg == MPU_PWR_MGMT_1 || reg == MPU_PWR_MGMT_2) {
            plant.mpu[reg] = bytes[k]; /* the writable configuration registers */
        }
    }
    return 0;
}

size_t host_world_i2c_read(uint8_t address, uint8_t *out, size_t n) {
    if (address != MPU_ADDRESS) {
        return 0;
    }
    for (size_t k = 0; k < n; k++) {
        out[k] = plant.mpu[plant.mpu_at];
        plant.mpu_at = (plant.mpu_at + 1) & 0x7f;
    }
    return n;
}
