/* The sphere's state and its own safety: levels, the master switch, the ON <ms> limit, the watchdog, the trip flag,
 * over-temperature, LED faults. The tick interrupt (1 kHz) only ever switches the light off; everything that
 * switches it on runs in the main loop with interrupts disabled, so an interrupt's switch-off is never undone. */
#ifndef SPHERE_H
#define SPHERE_H

#include <stdint.h>
#include "board.h"

typedef struct {
    uint16_t pwm[N_LEDS];
    uint8_t light;
    uint8_t trip;
    uint32_t ontime_ms;             /* since the light came on; 0 while off */
    uint32_t wdog_ms;
    int16_t temp_centi;
} sphere_status_t;

/* Power-up state: levels 0, light off, watchdog 30 s; ``trip`` set after a reset that ended a lit period the
 * host did not end (brown-out, watchdog, external reset; main.c decides from MCUSR). Starts the tick. */
void sphere_init(uint8_t trip, int16_t temp_centi);

/* A complete request line arrived (from the receive interrupt): restarts the watchdog. */
void sphere_request_seen(void);

/* 0, or the LED number (1-based) whose driver reports a fault while a non-zero level was asked (ERR 6). */
uint8_t sphere_set_level(uint8_t led, uint16_t pwm);
uint8_t sphere_set_levels(const uint32_t *pwm);     /* N_LEDS values, all or none */
void sphere_all_off(void);

/* 0, or 1 when the sphere is above its temperature limit (ERR 7; nothing changed). */
uint8_t sphere_light_on(uint8_t with_limit, uint32_t limit_ms);
void sphere_light_off(void);
void sphere_set_watchdog(uint32_t ms);

void sphere_status(sphere_status_t *out);
int16_t sphere_temperature(void);
uint32_t sphere_led_on_time(uint8_t led);           /* ms the LED (0-based) has been emitting */

/* Bit mask of driven LEDs reporting a fault; -1 while a driven LED's current sense has not settled yet. */
int32_t sphere_fault_mask(void);

#endif
