/* The stride Arduino link in portable C: see stride_link.h and SPEC.md. */
#include "stride_link.h"

#include <string.h>

uint16_t stride_link_crc16(const uint8_t *data, size_t n, uint16_t crc) {
    for (size_t i = 0; i < n; i++) {
        crc ^= (uint16_t)data[i] << 8;
        for (int b = 0; b < 8; b++) {
            crc = (crc & 0x8000) ? (uint16_t)((crc << 1) ^ 0x1021) : (uint16_t)(crc << 1);
        }
    }
    return crc;
}

size_t stride_link_encode(const stride_link_frame *f, uint8_t *out, size_t cap) {
    uint8_t raw[STRIDE_LINK_MAX_DECODED];
    size_t n = 0, o = 0, code_at;
    uint8_t code = 1;
    uint16_t crc;
    if (f->len > STRIDE_LINK_MAX_PAYLOAD || cap < STRIDE_LINK_MAX_ENCODED) {
        return 0;
    }
    raw[n++] = f->type;
    raw[n++] = f->seq;
    raw[n++] = f->len;
    memcpy(raw + n, f->payload, f->len);
    n += f->len;
    crc = stride_link_crc16(raw, n, 0xFFFF);
    raw[n++] = (uint8_t)(crc & 0xFF);
    raw[n++] = (uint8_t)(crc >> 8);
    /* COBS: each block is a code byte (distance to the next zero) and the non-zero bytes. */
    out[o++] = 0x00;
    code_at = o++;
    for (size_t i = 0; i < n; i++) {
        if (raw[i] == 0) {
            out[code_at] = code;
            code = 1;
            code_at = o++;
        } else {
            out[o++] = raw[i];
            if (++code == 0xFF) {
                out[code_at] = code;
                code = 1;
                code_at = o++;
            }
        }
    }
    out[code_at] = code;
    out[o++] = 0x00;
    return o;
}

void stride_link_decoder_init(stride_link_decoder *d) {
    memset(d, 0, sizeof *d);
}

/* Decodes the COBS block in d->buf into f; 1 good, -1 bad. */
static int finish(stride_link_decoder *d, stride_link_frame *f) {
    uint8_t raw[STRIDE_LINK_MAX_DECODED + 2];
    size_t i = 0, n = 0;
    while (i < d->n) {
        uint8_t code = d->buf[i++];
        if (code == 0 || i + code - 1 > d->n) {
            return -1;
        }
        for (uint8_t k = 1; k < code; k++) {
            if (n >= sizeof raw) {
                return -1;
            }
            raw[n++] = d->buf[i++];
        }
        if (code != 0xFF && i < d->n) {
            if (n >= sizeof raw) {
                return -1;
            }
            raw[n++] = 0;
        }
    }
    if (n < 5 || raw[2] > STRIDE_LINK_MAX_PAYLOAD || (size_t)raw[2] + 5 != n) {
        return -1;
    }
    if (stride_link_crc16(raw, n - 2, 0xFFFF) != (uint16_t)(raw[n - 2] | (uint16_t)raw[n - 1] << 8)) {
        return -1;
    }
    f->type = raw[0];
    f->seq = raw[1];
    f->len = raw[2];
    memcpy(f->payload, raw + 3, f->len);
    return 1;
}

int stride_link_decoder_push(stride_link_decoder *d, uint8_t byte, stride_link_frame *f) {
    int r;
    if (byte != 0) {
        if (d->n < sizeof d->buf) {
            d->buf[d->n++] = byte;
        } else {
            d->overflow = 1;
        }
        return 0;
    }
    if (d->n == 0 && !d->overflow) {
        return 0; /* delimiters back to back: nothing between them */
    }
    r = d->overflow ? -1 : finish(d, f);
    d->n = 0;
    d->overflow = 0;
    if (r == 1) {
        d->frames++;
    } else {
        d->bad++;
    }
    return r;
}

int stride_link_put_u8(stride_link_frame *f, uint8_t v) {
    if (f->len >= STRIDE_LINK_MAX_PAYLOAD) {
        return -1;
    }
    f->payload[f->len++] = v;
    return 0;
}

int stride_link_put_u16(stride_link_frame *f, uint16_t v) {
    if (f->len + 2 > STRIDE_LINK_MAX_PAYLOAD) {
        return -1;
    }
    f->payload[f->len++] = (uint8_t)(v & 0xFF);
    f->payload[f->len++] = (uint8_t)(v >> 8);
    return 0;
}

int stride_link_put_u32(stride_link_frame *f, uint32_t v) {
    if (f->len + 4 > STRIDE_LINK_MAX_PAYLOAD) {
        return -1;
    }
    for (int i = 0; i < 4; i++) {
        f->payload[f->len++] = (uint8_t)(v >> (8 * i));
    }
    return 0;
}

int stride_link_get_u8(const stride_link_frame *f, size_t *at, uint8_t *v) {
    if (*at + 1 > f->len) {
        return -1;
    }
    *v = f->payload[(*at)++];
    return 0;
}

int stride_link_get_u16(const stride_link_frame *f, size_t *at, uint16_t *v) {
    if (*at + 2 > f->len) {
        return -1;
    }
    *v = (uint16_t)(f->payload[*at] | (uint16_t)f->payload[*at + 1] << 8);
    *at += 2;
    return 0;
}

int stride_link_get_u32(const stride_link_frame *f, size_t *at, uint32_t *v) {
    if (*at + 4 > f->len) {
        return -1;
    }
    *v = (uint32_t)f->payload[*at] | (uint32_t)f->payload[*at + 1] << 8 |
         (uint32_t)f->payload[*at + 2] << 16 | (uint32_t)f->payload[*at + 3] << 24;
    *at += 4;
    return 0;
}
