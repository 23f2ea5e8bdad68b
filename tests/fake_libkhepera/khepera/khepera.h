/* khepera/khepera.h for khepera_gym's tests: the part of K-Team's libkhepera 2.1 interface that
 * the generated robot programs use, declared so that a program compiled against it compiles
 * against K-Team's own headers too, and behaves the same with the simulated robot of
 * fake_khepera4.c as with the real library.
 *
 * Written for khepera_gym from a reading of K-Team's installed headers (include/khepera/ of
 * libkhepera 2.1: knet.h, kb_error.h, kb_khepera4.h) and of its sources (kb_khepera4.c); none of
 * K-Team's text is copied (it carries no licence). Each group below says which K-Team header
 * declares the same names with the same values and types. Not shipped: khepera_gym's exports
 * include K-Team's own header on the robot.
 *
 * What the library returns (kb_khepera4.c), which the programs must follow:
 *   - every kh4_* call returns 0 when it succeeded, whatever its comment says ("the size of the
 *     frame", ">= 0 on success"): the reads too return 0, not the number of bytes;
 *   - a failure is any other value, and most are POSITIVE: KB_ERROR_KH4RCVERR (55) when a read
 *     over I2C failed, KB_ERROR_KH4SENERR (56) when a write failed, KB_ERROR_KH4KBNOTINIT (58)
 *     when the device handle is NULL; kh4_init returns KH4_ERROR_KBINIT (-1), and a write whose
 *     buffer cannot be allocated returns -ENOMEM. A program testing `rc < 0` misses most of them;
 *   - knet_open returns NULL when the device cannot be opened;
 *   - a failed read leaves the caller's buffer (or integers) undefined.
 */
#ifndef FAKE_KHEPERA_H
#define FAKE_KHEPERA_H

#include <pthread.h>

/* ---- As in K-Team's knet.h: the buses and the device handle. ---- */

/* The bus knet_open prefers (knet.h's KNET_BUS_* numbers). */
#define KNET_BUS_ANY -1
#define KNET_BUS_I2C 0
#define KNET_BUS_SPI 1
#define KNET_BUS_RS232 2
#define KNET_MAX_BUSSES 3

/* knet.h's scalar types of addresses and private data. */
typedef unsigned int knet_ext_t;
typedef unsigned int knet_mod_t;
typedef unsigned char knet_reg_t;
typedef void *knet_bus_info_t;
typedef void *knet_dev_info_t;

struct knet_dev_s;

/* knet.h's bus descriptor: the bus's operations, its devices, its lock and private data, in
 * K-Team's order. */
typedef struct knet_bus_s {
    int (*exit)(struct knet_bus_s *bus);
    struct knet_dev_s *(*open)(struct knet_bus_s *bus, knet_ext_t ext, knet_mod_t mod,
                               const char *name, int argc, char *argv[]);
    void (*close)(struct knet_bus_s *bus, struct knet_dev_s *device);
    int (*transfer)(struct knet_bus_s *bus, struct knet_dev_s *device, const char *write_buf,
                    unsigned int write_len, char *read_buf, unsigned read_len);
    int (*read)(struct knet_bus_s *bus, struct knet_dev_s *device, char *buf, unsigned int len);
    int (*write)(struct knet_bus_s *bus, struct knet_dev_s *device, const char *buf,
                 unsigned int len);
    struct knet_dev_s *devices;
    pthread_mutex_t lock;
    knet_bus_info_t bus_info;
    int usage_counter;
} knet_bus_t;

/* knet.h's device descriptor (a whole struct there, not an opaque type): its bus, byte order,
 * addresses, name, users, private data and the next device of the bus, in K-Team's order. */
typedef struct knet_dev_s {
    knet_bus_t *bus;
    unsigned long order;
    knet_ext_t ext_addr;
    knet_mod_t mod_addr;
    const char *name;
    unsigned int usage_counter;
    knet_dev_info_t info;
    struct knet_dev_s *next;
} knet_dev_t;

/* knet.h: opens the device of that name ("Khepera4:dsPic"); NULL on failure. */
extern knet_dev_t *knet_open(const char *name, int preferred_bus, int argc, char *argv[]);

/* ---- As in K-Team's kb_error.h: the error numbers the Khepera IV calls return. ---- */

#define KB_ERROR_KH4RCVERR 55    /* a read from the dsPIC failed */
#define KB_ERROR_KH4SENERR 56    /* a write to the dsPIC failed */
#define KB_ERROR_KH4KBINIT 57    /* the library could not be initialised (reported, not returned) */
#define KB_ERROR_KH4KBNOTINIT 58 /* the device handle is NULL */

/* ---- As in K-Team's kb_khepera4.h: its codes, the robot's constants, the motor modes and the
 * calls. ---- */

#define KH4_ERROR_SUCCESS 0
#define KH4_ERROR_KBINIT -1 /* kh4_init: the library could not be initialised */
#define KH4_ERROR_FRMSZ -2
#define KH4_ERROR_SZFMT -3
#define KH4_ERROR_FRMSND -4
#define KH4_ERROR_GPIO -5

#define KH4_WHEELS_DISTANCE 105.4          /* mm between the wheels */
#define KH4_PULSE_TO_MM 0.006781           /* mm a wheel travels per encoder pulse */
#define KH4_TIME_BTWN 10                   /* ms: the period of the speed unit */
#define KH4_SPEED_TO_MM_S 0.6781           /* mm/s per speed unit */
#define KH4_GYRO_DEG_S (66.0 / 1000.0)     /* deg/s per gyroscope count */
#define KH4_MAX_IR_VALUE 1024              /* the infrared sensors' 10-bit span */
#define KH4_MAX_OPENLOOP_SPEED_PWM_100 2940 /* open loop: the PWM value of 100 % */
#define KH4_US_DISABLED_SENSOR 2000        /* an ultrasonic sensor switched off */
#define KH4_US_NO_OBJECT_IN_RANGE 1000     /* nothing within 25..250 cm */
#define KH4_US_OBJECT_NEAR 0               /* something nearer than 25 cm */

/* The motor controller's modes, the five of kb_khepera4.h with its values. */
enum kh4RegType {
    kh4RegIdle = 0,
    kh4RegSpeed = 1,
    kh4RegSpeedProfile = 2,
    kh4RegPosition = 3,
    kh4RegSOpenLoop = 4,
};

/* kb_khepera4.h's calls the programs make, with its types (K-Team names no parameters; the names
 * here say what each is). Buffers are filled little-endian, 16 bits a value:
 *   kh4_revision        1 byte: version (high nibble, 0 = 'A') and revision (low nibble);
 *   kh4_proximity_ir    24 bytes: 12 values, the ring BL, L, FL, F, FR, R, BR, B then the
 *                       ground sensors GL, GFL, GFR, GR, 0..1023;
 *   kh4_measure_us      10 bytes: 5 values L, FL, F, FR, R in cm, or the KH4_US_* codes;
 *   kh4_measure_acc     60 bytes: 10 samples of X, then 10 of Y, then 10 of Z, newest first;
 *   kh4_measure_gyro    60 bytes, the same layout.
 * kh4_get_speed and kh4_get_position write signed integers (speed units; pulses).
 * kh4_activate_us's mask: bit 0 left ... bit 4 right (31: all). kh4_SetRGBLeds keeps 6 bits of
 * each level. kh4_set_speed sends the low 16 bits of each speed. */
extern int kh4_init(int argc, char *argv[]);
extern int kh4_revision(char *buffer, knet_dev_t *device);
extern int kh4_SetRGBLeds(char left_red, char left_green, char left_blue, char right_red,
                          char right_green, char right_blue, char back_red, char back_green,
                          char back_blue, knet_dev_t *device);
extern int kh4_SetMode(int mode, knet_dev_t *device);
extern int kh4_SetSpeedProfile(char acc_inc, char acc_div, char min_speed_acc, char min_speed_dec,
                               int max_speed, knet_dev_t *device);
extern int kh4_get_position(int *left, int *right, knet_dev_t *device);
extern int kh4_get_speed(int *left, int *right, knet_dev_t *device);
extern int kh4_set_speed(int left, int right, knet_dev_t *device);
extern int kh4_ResetEncoders(knet_dev_t *device);
extern int kh4_proximity_ir(char *buffer, knet_dev_t *device);
extern int kh4_measure_us(char *buffer, knet_dev_t *device);
extern int kh4_measure_acc(char *buffer, knet_dev_t *device);
extern int kh4_measure_gyro(char *buffer, knet_dev_t *device);
extern int kh4_activate_us(char mask, knet_dev_t *device);

#endif
