/*
 * The stride Arduino link (SPEC.md, version 1.0) in portable C: COBS framing, CRC-16/CCITT,
 * frame encoding and a byte-at-a-time decoder. No allocation, no I/O, no libc beyond
 * <stdint.h>/<stddef.h>/<string.h>: fit for an ATmega32U4 and the Due, and for the host.
 */
#ifndef STRIDE_LINK_H
#define STRIDE_LINK_H

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

#define STRIDE_LINK_MAJOR 1
#define STRIDE_LINK_MINOR 0

/* Largest payload, decoded frame (type, seq, len, payload, crc) and encoded frame (COBS
 * overhead and the 0x00 delimiter). */
#define STRIDE_LINK_MAX_PAYLOAD 240
#define STRIDE_LINK_MAX_DECODED (STRIDE_LINK_MAX_PAYLOAD + 5)
#define STRIDE_LINK_MAX_ENCODED (STRIDE_LINK_MAX_DECODED + 4)

/* Message types. */
#define STRIDE_LINK_HELLO 0x01
#define STRIDE_LINK_HEARTBEAT 0x02
#define STRIDE_LINK_COMMAND 0x10
#define STRIDE_LINK_HELLO_ACK 0x81
#define STRIDE_LINK_HEARTBEAT_ACK 0x82
#define STRIDE_LINK_NACK 0x8F
#define STRIDE_LINK_STATE 0x90
#define STRIDE_LINK_IMU 0x91
#define STRIDE_LINK_FAULT 0x92

/* COMMAND modes. */
#define STRIDE_LINK_MODE_COAST 0
#define STRIDE_LINK_MODE_DUTY 1
#define STRIDE_LINK_MODE_BRAKE 2
#define STRIDE_LINK_MODE_POSITION 3

/* Fault bits. */
#define STRIDE_LINK_FAULT_OVER_CURRENT 1
#define STRIDE_LINK_FAULT_OVER_TEMPERATURE 2
#define STRIDE_LINK_FAULT_WATCHDOG 4
#define STRIDE_LINK_FAULT_DRIVER 8
#define STRIDE_LINK_FAULT_LINK 16

/* NACK reasons. */
#define STRIDE_LINK_NACK_TYPE 1
#define STRIDE_LINK_NACK_PAYLOAD 2
#define STRIDE_LINK_NACK_RANGE 3
#define STRIDE_LINK_NACK_VERSION 4
#define STRIDE_LINK_NACK_NO_HANDSHAKE 5

/* A decoded frame. */
typedef struct {
    uint8_t type;
    uint8_t seq;
    uint8_t len;
    uint8_t payload[STRIDE_LINK_MAX_PAYLOAD];
} stride_link_frame;

/* CRC-16/CCITT-FALSE of n bytes, continuing from crc (0xFFFF to start). */
uint16_t stride_link_crc16(const uint8_t *data, size_t n, uint16_t crc);

/* Encodes f (0x00, COBS, 0x00) into out; returns the bytes written, or 0 when
 * the payload is too long or out is too small (STRIDE_LINK_MAX_ENCODED always suffices). */
size_t stride_link_encode(const stride_link_frame *f, uint8_t *out, size_t cap);

/* A decoder that takes the line byte by byte. */
typedef struct {
    uint8_t buf[STRIDE_LINK_MAX_ENCODED];
    size_t n;
    uint8_t overflow;
    uint32_t frames;     /* good frames */
    uint32_t bad;        /* frames dropped: bad COBS, length or CRC, too long */
} stride_link_decoder;

void stride_link_decoder_init(stride_link_decoder *d);

/* Feeds one byte. Returns 1 when it completed a good frame (written to *f), -1 when it
 * completed a bad one (counted, dropped), 0 otherwise. */
int stride_link_decoder_push(stride_link_decoder *d, uint8_t byte, stride_link_frame *f);

/* Little-endian field helpers: put advances *at and returns 0, or -1 when the payload is full;
 * get advances *at and returns 0, or -1 past the payload's length. */
int stride_link_put_u8(stride_link_frame *f, uint8_t v);
int stride_link_put_u16(stride_link_frame *f, uint16_t v);
int stride_link_put_u32(stride_link_frame *f, uint32_t v);
int stride_link_get_u8(const stride_link_frame *f, size_t *at, uint8_t *v);
int stride_link_get_u16(const stride_link_frame *f, size_t *at, uint16_t *v);
int stride_link_get_u32(const stride_link_frame *f, size_t *at, uint32_t *v);

#ifdef __cplusplus
}
#endif

#endif
