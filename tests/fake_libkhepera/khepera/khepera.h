/* khepera/khepera.h for khepera_gym's tests: declarations of the libkhepera calls the generated
 * robot programs use, written from K-Team's documented signatures (kb_khepera4.h, docs/robot.md
 * §10 of khepera_gym) only to build the programs against the simulated robot of
 * fake_khepera4.c. This is not K-Team's header and is not shipped.
 */
#ifndef FAKE_KHEPERA_H
#define FAKE_KHEPERA_H

typedef struct knet_dev_s knet_dev_t;
#define KNET_BUS_I2C 1
enum kh4RegType { kh4RegIdle = 0, kh4RegSpeed = 1, kh4RegSpeedProfile = 2 };

int kh4_init(int argc, char *argv[]);
knet_dev_t *knet_open(const char *name, int bus, int argc, char *argv[]);
int kh4_SetMode(int mode, knet_dev_t *device);
int kh4_SetSpeedProfile(char accinc, char accdiv, char mindacc, char mindec, int max_speed,
                        knet_dev_t *device);
int kh4_set_speed(int left, int right, knet_dev_t *device);
int kh4_get_speed(int *left, int *right, knet_dev_t *device);
int kh4_get_position(int *left, int *right, knet_dev_t *device);
int kh4_ResetEncoders(knet_dev_t *device);
int kh4_proximity_ir(char *buffer, knet_dev_t *device);
int kh4_measure_us(char *buffer, knet_dev_t *device);
int kh4_activate_us(char mask, knet_dev_t *device);
int kh4_measure_acc(char *buffer, knet_dev_t *device);
int kh4_measure_gyro(char *buffer, knet_dev_t *device);
int kh4_revision(char *buffer, knet_dev_t *device);
int kh4_SetRGBLeds(char left_r, char left_g, char left_b, char right_r, char right_g, char right_b,
                   char back_r, char back_g, char back_b, knet_dev_t *device);

#endif
