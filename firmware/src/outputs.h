/* The 10 PWM outputs (board.h). */
#ifndef OUTPUTS_H
#define OUTPUTS_H

#include <stdint.h>
#include "board.h"

/* Pins to output low, timers configured (mode 14, TOP = PWM_TOP) and stopped. */
void outputs_init(void);

/* Every output low at once: compare outputs disconnected, port bits low, timers stopped. Only 8-bit registers:
 * safe from an interrupt while the main loop is between the two halves of a 16-bit register write. */
void outputs_dark(void);

/* Emit ``pwm`` (0..65535 per LED) while ``light`` is on; dark otherwise. Call with interrupts disabled. */
void outputs_apply(uint8_t light, const uint16_t *pwm);

#endif
