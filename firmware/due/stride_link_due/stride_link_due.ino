/*
 * stride_link_due: firmware for the Arduino Due of one of Archie's legs. It speaks the stride
 * Arduino link (drivers/arduino-link/SPEC.md) with the host over the programming port, drives
 * six BLD-70 brushless drivers (PWM, direction, brake, each behind an Arduino Micro that
 * passes the signals through and reads the driver's current), reads the MPU-6050 at the hip
 * over I2C, and brakes every motor when commands stop (the watchdog) or a current trips.
 *
 * The link codec is the portable C one (stride_link.h / stride_link.c, copied next to this
 * sketch by `scripts/firmware`). The host's tests run this very sketch as their fake board
 * (drivers/fakes: compiled against firmware/host-stubs, with simulated joints and IMU behind
 * the pins), so what they exercise is what ships.
 */
#include <Arduino.h>
#include <Wire.h>

#include "stride_link.h"

static const uint8_t JOINTS = 6;
static const uint8_t PWM_PIN[JOINTS] = {2, 3, 4, 5, 6, 7};
static const uint8_t DIR_PIN[JOINTS] = {22, 24, 26, 28, 30, 32};
static const uint8_t BRAKE_PIN[JOINTS] = {23, 25, 27, 29, 31, 33};
static const uint8_t CURRENT_PIN[JOINTS] = {A0, A1, A2, A3, A4, A5};
static const uint16_t WATCHDOG_MS = 100;
static const uint16_t MAX_DUTY = 9000;         /* 1/10000 */
static const uint16_t CURRENT_LIMIT_MA = 8000;
static const uint8_t MPU_ADDRESS = 0x68;

static stride_link_decoder decoder;
static uint8_t tx_seq = 0;
static uint8_t last_command_seq = 0;
static bool session = false;
static bool watchdog_tripped = false;
static uint32_t last_alive_ms = 0;
static uint32_t next_state_ms = 0;
static uint32_t next_imu_ms = 0;

struct Joint {
    uint8_t mode;
    int16_t duty;      /* 1/10000 */
    int16_t target;    /* 1/10000 rad, position mode */
    int32_t position;  /* 1e-5 rad, from the driver's hall counts */
    int16_t current_ma;
    uint8_t faults;
    bool braked;
};
static Joint joint[JOINTS];

static void send(stride_link_frame *f) {
    uint8_t buf[STRIDE_LINK_MAX_ENCODED];
    f->seq = tx_seq++;
    size_t n = stride_link_encode(f, buf, sizeof buf);
    if (n) {
        Serial.write(buf, n);
    }
}

static void apply(uint8_t j) {
    Joint &m = joint[j];
    int16_t duty = m.braked ? 0 : m.duty;
    digitalWrite(BRAKE_PIN[j], m.braked ? HIGH : LOW);
    digitalWrite(DIR_PIN[j], duty < 0 ? HIGH : LOW);
    analogWrite(PWM_PIN[j], (int)((long)abs(duty) * 4095 / 10000));
}

static void brake_all(void) {
    for (uint8_t j = 0; j < JOINTS; j++) {
        joint[j].mode = STRIDE_LINK_MODE_BRAKE;
        joint[j].duty = 0;
        joint[j].braked = true;
        apply(j);
    }
}

static void nack(uint8_t seq, uint8_t reason) {
    stride_link_frame f;
    f.type = STRIDE_LINK_NACK;
    f.len = 0;
    stride_link_put_u8(&f, seq);
    stride_link_put_u8(&f, reason);
    send(&f);
}

static void on_frame(const stride_link_frame *f) {
    size_t at = 0;
    stride_link_frame r;
    if (f->type == STRIDE_LINK_HELLO) {
        uint8_t major, minor;
        uint32_t nonce;
        if (stride_link_get_u8(f, &at, &major) || stride_link_get_u8(f, &at, &minor) ||
            stride_link_get_u32(f, &at, &nonce)) {
            nack(f->seq, STRIDE_LINK_NACK_PAYLOAD);
            return;
        }
        if (major != STRIDE_LINK_MAJOR) {
            nack(f->seq, STRIDE_LINK_NACK_VERSION);
            return;
        }
        brake_all();
        tx_seq = 0;
        session = true;
        watchdog_tripped = false;
        last_alive_ms = millis();
        r.type = STRIDE_LINK_HELLO_ACK;
        r.len = 0;
        stride_link_put_u8(&r, STRIDE_LINK_MAJOR);
        stride_link_put_u8(&r, STRIDE_LINK_MINOR);
        stride_link_put_u32(&r, nonce);
        stride_link_put_u8(&r, JOINTS);
        stride_link_put_u16(&r, WATCHDOG_MS);
        stride_link_put_u16(&r, MAX_DUTY);
        stride_link_put_u16(&r, CURRENT_LIMIT_MA);
        const char name[16] = "stride-due 1.0";
        for (uint8_t i = 0; i < 16; i++) {
            stride_link_put_u8(&r, (uint8_t)name[i]);
        }
        send(&r);
        return;
    }
    if (!session) {
        nack(f->seq, STRIDE_LINK_NACK_NO_HANDSHAKE);
        return;
    }
    if (f->type == STRIDE_LINK_HEARTBEAT) {
        last_alive_ms = millis();
        r.type = STRIDE_LINK_HEARTBEAT_ACK;
        r.len = 0;
        stride_link_put_u32(&r, millis());
        send(&r);
        return;
    }
    if (f->type != STRIDE_LINK_COMMAND) {
        nack(f->seq, STRIDE_LINK_NACK_TYPE);
        return;
    }
    uint8_t count, ji[JOINTS], mode[JOINTS];
    uint16_t raw[JOINTS];
    if (stride_link_get_u8(f, &at, &count) || count > JOINTS) {
        nack(f->seq, STRIDE_LINK_NACK_PAYLOAD);
        return;
    }
    for (uint8_t k = 0; k < count; k++) {
        if (stride_link_get_u8(f, &at, &ji[k]) || stride_link_get_u8(f, &at, &mode[k]) ||
            stride_link_get_u16(f, &at, &raw[k])) {
            nack(f->seq, STRIDE_LINK_NACK_PAYLOAD);
            return;
        }
        if (ji[k] >= JOINTS || mode[k] > STRIDE_LINK_MODE_POSITION ||
            (mode[k] == STRIDE_LINK_MODE_DUTY && abs((int16_t)raw[k]) > MAX_DUTY)) {
            nack(f->seq, STRIDE_LINK_NACK_RANGE);
            return;
        }
    }
    last_alive_ms = millis();
    watchdog_tripped = false;
    last_command_seq = f->seq;
    for (uint8_t k = 0; k < count; k++) {
        Joint &m = joint[ji[k]];
        if ((m.faults & STRIDE_LINK_FAULT_OVER_CURRENT) && mode[k] != STRIDE_LINK_MODE_COAST &&
            mode[k] != STRIDE_LINK_MODE_BRAKE) {
            continue; /* stays braked until told to coast or brake */
        }
        m.faults = 0;
        m.mode = mode[k];
        m.braked = mode[k] == STRIDE_LINK_MODE_BRAKE;
        m.duty = mode[k] == STRIDE_LINK_MODE_DUTY ? (int16_t)raw[k] : 0;
        m.target = mode[k] == STRIDE_LINK_MODE_POSITION ? (int16_t)raw[k] : m.target;
        apply(ji[k]);
    }
}

static int16_t mpu_word(void) {
    int16_t hi = Wire.read();
    return (int16_t)(hi << 8 | Wire.read());
}

static void send_imu(void) {
    stride_link_frame f;
    Wire.beginTransmission(MPU_ADDRESS);
    Wire.write(0x3B); /* ACCEL_XOUT_H: then accel, temperature, gyro */
    Wire.endTransmission(false);
    if (Wire.requestFrom(MPU_ADDRESS, (uint8_t)14) != 14) {
        return;
    }
    f.type = STRIDE_LINK_IMU;
    f.len = 0;
    stride_link_put_u32(&f, micros());
    for (uint8_t i = 0; i < 7; i++) {
        stride_link_put_u16(&f, (uint16_t)mpu_word());
    }
    send(&f);
}

static void send_state(void) {
    stride_link_frame f;
    f.type = STRIDE_LINK_STATE;
    f.len = 0;
    stride_link_put_u32(&f, millis());
    stride_link_put_u8(&f, last_command_seq);
    stride_link_put_u8(&f, JOINTS);
    for (uint8_t j = 0; j < JOINTS; j++) {
        Joint &m = joint[j];
        stride_link_put_u32(&f, (uint32_t)m.position);
        stride_link_put_u16(&f, 0); /* velocity: from the hall period, not wired yet */
        stride_link_put_u16(&f, (uint16_t)m.current_ma);
        stride_link_put_u8(&f, 0);  /* temperature: no sensor on this board */
        stride_link_put_u16(&f, (uint16_t)m.duty);
        stride_link_put_u8(&f, (uint8_t)((m.braked ? 1 : 0) | m.faults << 1));
    }
    send(&f);
}

void setup() {
    Serial.begin(115200);
    analogWriteResolution(12);
    analogReadResolution(12);
    for (uint8_t j = 0; j < JOINTS; j++) {
        pinMode(DIR_PIN[j], OUTPUT);
        pinMode(BRAKE_PIN[j], OUTPUT);
    }
    brake_all();
    Wire.begin();
    Wire.beginTransmission(MPU_ADDRESS);
    Wire.write(0x6B); /* PWR_MGMT_1: wake up */
    Wire.write(0);
    Wire.endTransmission(true);
    stride_link_decoder_init(&decoder);
}

void loop() {
    stride_link_frame f;
    while (Serial.available() > 0) {
        if (stride_link_decoder_push(&decoder, (uint8_t)Serial.read(), &f) == 1) {
            on_frame(&f);
        }
    }
    uint32_t now = millis();
    for (uint8_t j = 0; j < JOINTS; j++) {
        /* ACS711-style sensor on the driver: 0..3.3 V over 12 bits, 2.5 A per volt. */
        joint[j].current_ma = (int16_t)((long)analogRead(CURRENT_PIN[j]) * 3300L / 4095L * 25L / 10L);
        if (joint[j].current_ma > CURRENT_LIMIT_MA && !(joint[j].faults & STRIDE_LINK_FAULT_OVER_CURRENT)) {
            joint[j].faults |= STRIDE_LINK_FAULT_OVER_CURRENT;
            joint[j].braked = true;
            joint[j].duty = 0;
            apply(j);
            stride_link_frame e;
            e.type = STRIDE_LINK_FAULT;
            e.len = 0;
            stride_link_put_u8(&e, j);
            stride_link_put_u8(&e, STRIDE_LINK_FAULT_OVER_CURRENT);
            stride_link_put_u16(&e, (uint16_t)joint[j].current_ma);
            send(&e);
        }
    }
    if (session && !watchdog_tripped && now - last_alive_ms > WATCHDOG_MS) {
        watchdog_tripped = true;
        brake_all();
        for (uint8_t j = 0; j < JOINTS; j++) {
            joint[j].faults |= STRIDE_LINK_FAULT_WATCHDOG;
        }
        stride_link_frame e;
        e.type = STRIDE_LINK_FAULT;
        e.len = 0;
        stride_link_put_u8(&e, 0xFF);
        stride_link_put_u8(&e, STRIDE_LINK_FAULT_WATCHDOG);
        stride_link_put_u16(&e, WATCHDOG_MS);
        send(&e);
    }
    if (session && (int32_t)(now - next_state_ms) >= 0) {
        next_state_ms = now + 10;
        send_state();
    }
    if (session && (int32_t)(now - next_imu_ms) >= 0) {
        next_imu_ms = now + 10;
        send_imu();
    }
}
