/* The sphere's sensors: per-LED current sense and driver fault flags, and the heat sink's temperature. */
#ifndef INPUTS_H
#define INPUTS_H

#include <stdint.h>

void inputs_init(void);

/* One reading (TEMP_SAMPLES conversions) before the tick runs, so the first request already has a temperature. */
int16_t inputs_first_temperature(void);

/* From the tick interrupt, once per millisecond: takes the last conversion and starts the next; returns 1 and
 * sets *centi (hundredths of a degree C) when a new reading is complete. */
uint8_t inputs_tick(int16_t *centi);

/* LED 0..N_LEDS-1: its driver reports a fault (flag low). */
uint8_t inputs_driver_fault(uint8_t led);

/* LED 0..N_LEDS-1: current flowed through it within the sense's hold time. */
uint8_t inputs_current(uint8_t led);

#endif
