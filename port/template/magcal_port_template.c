/*
 * magcal port template: copy this file into your firmware, fill in the TODO blocks, and
 * link it instead of any other port. It compiles as shipped (with the I2C calls stubbed to
 * report MAGCAL_ERR_PORT) so the build checks it against the port header.
 *
 * What a port must do (see magcal_port.h):
 *  1. read the sensor when its data-ready flag is set, within one sample period;
 *  2. convert raw registers to a documented unit (this template: microtesla);
 *  3. map the sensor's axes onto the body frame x right, y forward, z up;
 *  4. return MAGCAL_ERR_TIMEOUT when no sample is ready and MAGCAL_ERR_PORT on a bus error.
 *
 * Several magnetometers: list each one's I2C address in port_mag_addr[] (sensor index = position;
 * sensor 0 is what magcal_port_mag_read() reads) and poll each calibrator with
 * magcal_calibrator_poll_n(cal, index). A single-sensor board may delete magcal_port_mag_read_n().
 *
 * Example numbers are for an LIS3MDL-class magnetometer (+/-4 gauss range, 6842 LSB/gauss,
 * 1 gauss = 100 uT) and an accelerometer at +/-2 g (16384 LSB/g); replace them with your part's.
 */
#include <stdint.h>

#include "magcal_port.h"

/* ---- board configuration (edit) --------------------------------------------------------- */
#define PORT_MAG_I2C_ADDR 0x1Cu        /* 7-bit address of sensor 0 (SDO/SA1 low) */
#define PORT_MAG2_I2C_ADDR 0x1Eu       /* sensor 1: the same part with SDO/SA1 high */
#define PORT_MAG_REG_STATUS 0x27u      /* bit 3 (ZYXDA): new x/y/z data ready */
#define PORT_MAG_REG_OUT_X_L 0x28u     /* 6 bytes: X_L X_H Y_L Y_H Z_L Z_H, little endian */
#define PORT_MAG_STATUS_DRDY 0x08u
#define PORT_MAG_UT_PER_LSB (100.0f / 6842.0f)
#define PORT_ACC_I2C_ADDR 0x6Au
#define PORT_ACC_REG_OUT_X_L 0x28u
#define PORT_ACC_G_PER_LSB (1.0f / 16384.0f)
#define PORT_DRDY_POLLS 8u             /* bounded wait for data-ready */

/* ---- platform hooks (replace with your HAL / RTOS calls) -------------------------------- */
/* TODO: return 0 on success, non-zero on a bus error (NACK, arbitration lost, timeout). */
static int board_i2c_read(uint8_t addr, uint8_t reg, uint8_t *buf, uint32_t len)
{
    (void)addr;
    (void)reg;
    (void)buf;
    (void)len;
    return -1; /* not wired yet: every read reports a port error */
}

/* TODO: a free-running millisecond counter (SysTick, RTOS tick). */
static uint32_t board_millis(void)
{
    return 0u;
}

/* ---- conversions ------------------------------------------------------------------------- */
static int16_t le16(const uint8_t *p)
{
    return (int16_t)(uint16_t)((uint16_t)p[0] | (uint16_t)((uint16_t)p[1] << 8));
}

/* 7-bit addresses of the magnetometers, by sensor index (edit: one entry per sensor fitted). */
static const uint8_t port_mag_addr[] = {PORT_MAG_I2C_ADDR, PORT_MAG2_I2C_ADDR};
#define PORT_MAG_COUNT (sizeof port_mag_addr / sizeof port_mag_addr[0])

magcal_status_t magcal_port_mag_read(magcal_vec3_t *out)
{
    return magcal_port_mag_read_n(0u, out);
}

magcal_status_t magcal_port_mag_read_n(uint8_t sensor, magcal_vec3_t *out)
{
    uint8_t addr;
    uint8_t status = 0u;
    uint8_t raw[6];
    uint32_t tries;
    if (out == 0) {
        return MAGCAL_ERR_NULL;
    }
    if (sensor >= PORT_MAG_COUNT) {
        return MAGCAL_ERR_ARG;
    }
    addr = port_mag_addr[sensor];
    for (tries = 0u; tries < PORT_DRDY_POLLS; ++tries) {
        if (board_i2c_read(addr, PORT_MAG_REG_STATUS, &status, 1u) != 0) {
            return MAGCAL_ERR_PORT;
        }
        if ((status & PORT_MAG_STATUS_DRDY) != 0u) {
            break;
        }
    }
    if ((status & PORT_MAG_STATUS_DRDY) == 0u) {
        return MAGCAL_ERR_TIMEOUT;
    }
    if (board_i2c_read(addr, PORT_MAG_REG_OUT_X_L, raw, 6u) != 0) {
        return MAGCAL_ERR_PORT;
    }
    /* TODO axis mapping: this assumes the sensor's silk-screen x/y/z already match
     * x right / y forward / z up. For an x-forward, y-left part use x = -sy, y = sx. */
    out->x = (float)le16(&raw[0]) * PORT_MAG_UT_PER_LSB;
    out->y = (float)le16(&raw[2]) * PORT_MAG_UT_PER_LSB;
    out->z = (float)le16(&raw[4]) * PORT_MAG_UT_PER_LSB;
    return MAGCAL_OK;
}

magcal_status_t magcal_port_accel_read(magcal_vec3_t *out)
{
    uint8_t raw[6];
    if (out == 0) {
        return MAGCAL_ERR_NULL;
    }
    if (board_i2c_read(PORT_ACC_I2C_ADDR, PORT_ACC_REG_OUT_X_L, raw, 6u) != 0) {
        return MAGCAL_ERR_PORT;
    }
    out->x = (float)le16(&raw[0]) * PORT_ACC_G_PER_LSB;
    out->y = (float)le16(&raw[2]) * PORT_ACC_G_PER_LSB;
    out->z = (float)le16(&raw[4]) * PORT_ACC_G_PER_LSB;
    return MAGCAL_OK;
}

uint32_t magcal_port_millis(void)
{
    return board_millis();
}
