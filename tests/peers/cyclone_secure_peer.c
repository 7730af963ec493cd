/* An independent (secured) DDS peer for interop tests: Eclipse Cyclone DDS 0.10 in C, with the
 * DDS-Security plugins Debian builds with OpenSSL, speaking ROS 2's names on DDS.
 *
 *   cyclone_secure_peer [--enclave DIR] [--plugins DIR] [--trace FILE] [--domain N]
 *                       [--cloud-topic T] [--points FILE] [--frame F]
 *                       [--float-topic T] [--timeout S] [--count N] [--monitor]
 *                       [--no-cloud] [--no-float] [--cdr FILE] [--rate HZ]
 *
 * Default: publishes a sensor_msgs/PointCloud2 on --cloud-topic (rt/camera/depth/points) at
 * 10 Hz, best effort as camera drivers do, and reads std_msgs/Float64 on --float-topic
 * (rt/ist_monitor/min_distance), reliable, until --count values (default: none, i.e. the whole
 * --timeout, default 30 s) came in. The cloud is the points of --points (text: "x y z" per line,
 * '#' comments) or, without it, the plane tests/python/cyclonedds_interop.py sends (20 x 20 points
 * 0.6 m ahead of camera_link); fields x y z float32 and a 4-byte pad, point_step 16.
 * --monitor: the other role, for a Cyclone-only check: reads the clouds on --cloud-topic and
 * answers each with the distance of its nearest point to the origin on --float-topic.
 *
 * --cdr FILE: publish this cloud instead, a serialized sensor_msgs/PointCloud2 as a bag holds it
 * (CDR, little endian, with its 4-byte encapsulation header; e.g. the real Kinect frame), its
 * stamp replaced by the time of each write. --rate HZ: the clouds' rate (default 10), paced
 * from the start (a late write is not made up for).
 *
 * --no-cloud, --no-float: leave that side out (a process per enclave: in the cell policy the camera
 * publishes the cloud and the operator reads the outputs). A reader or writer the local
 * permissions deny is not fatal: the JSON's "cloud_entity" / "float_entity" says "denied" with
 * Cyclone's return code ("ok" or "none" otherwise).
 *
 * At the end it prints one JSON line: {"values": [...floats received...], "clouds_sent": n,
 * "clouds_received": n, "cloud_matched": readers (or writers) of the cloud topic ever matched,
 * "float_matched": likewise for the float topic}. Exit 0 unless the domain, participant or a topic could not be made
 * (then 2, with Cyclone's reason on stderr).
 *
 * --enclave DIR: an SROS2 enclave folder (cert.pem, key.pem, identity_ca.cert.pem,
 * permissions_ca.cert.pem, governance.p7s, permissions.p7s): the participant is secured with
 * Cyclone's auth/access-control/crypto plugins from --plugins (Debian's folder by default), the
 * files given as rmw_cyclonedds_cpp gives them. --trace FILE: Cyclone's finest trace there.
 */
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "dds/dds.h"
#include "ros_msgs.h"

#define MAX_VALUES 4096
#define DEFAULT_PLUGINS "/usr/lib/x86_64-linux-gnu/libddsc0debian"

struct options {
  const char *enclave, *plugins, *trace, *cloud_topic, *float_topic, *points, *frame, *cdr;
  int domain, count, monitor, no_cloud, no_float;
  double timeout, rate;
};

static void die(const char *what, dds_return_t rc) {
  fprintf(stderr, "cyclone_secure_peer: %s: %s\n", what, dds_strretcode(rc));
  exit(2);
}

static double now_s(void) {
  struct timespec t;
  clock_gettime(CLOCK_REALTIME, &t);
  return (double)t.tv_sec + (double)t.tv_nsec * 1e-9;
}

/* The domain configuration: security (the enclave's six files) and tracing, or NULL. */
static char *config_xml(const struct options *o) {
  static char xml[8192];
  char security[6144] = "", tracing[1024] = "";
  if (o->enclave) {
    const char *e = o->enclave, *p = o->plugins;
    snprintf(security, sizeof security,
             "<Security><Authentication>"
             "<Library path=\"%s/libdds_security_auth.so\" initFunction=\"init_authentication\""
             " finalizeFunction=\"finalize_authentication\"/>"
             "<IdentityCA>file:%s/identity_ca.cert.pem</IdentityCA>"
             "<IdentityCertificate>file:%s/cert.pem</IdentityCertificate>"
             "<PrivateKey>file:%s/key.pem</PrivateKey></Authentication>"
             "<AccessControl>"
             "<Library path=\"%s/libdds_security_ac.so\" initFunction=\"init_access_control\""
             " finalizeFunction=\"finalize_access_control\"/>"
             "<PermissionsCA>file:%s/permissions_ca.cert.pem</PermissionsCA>"
             "<Governance>file:%s/governance.p7s</Governance>"
             "<Permissions>file:%s/permissions.p7s</Permissions></AccessControl>"
             "<Cryptographic>"
             "<Library path=\"%s/libdds_security_crypto.so\" initFunction=\"init_crypto\""
             " finalizeFunction=\"finalize_crypto\"/></Cryptographic></Security>",
             p, e, e, e, p, e, e, e, p);
  }
  if (o->trace) {
    snprintf(tracing, sizeof tracing,
             "<Tracing><Verbosity>finest</Verbosity><OutputFile>%s</OutputFile></Tracing>",
             o->trace);
  }
  if (!o->enclave && !o->trace) return NULL;
  snprintf(xml, sizeof xml, "<CycloneDDS><Domain id=\"any\">%s%s</Domain></CycloneDDS>", security,
           tracing);
  return xml;
}

/* The points of the cloud, as float triples: from the file, or the interop plane. */
static float *load_points(const char *path, uint32_t *n) {
  size_t cap = 400, len = 0;
  float *xyz = malloc(cap * 3 * sizeof *xyz);
  if (!path) {
    for (int i = 0; i < 20; i++)
      for (int j = 0; j < 20; j++, len++) {
        xyz[3 * len] = 0.6f;
        xyz[3 * len + 1] = -0.2f + 0.02f * (float)i;
        xyz[3 * len + 2] = -0.2f + 0.02f * (float)j;
      }
    *n = (uint32_t)len;
    return xyz;
  }
  FILE *f = fopen(path, "r");
  if (!f) {
    fprintf(stderr, "cyclone_secure_peer: --points %s: %s\n", path, strerror(errno));
    exit(2);
  }
  char line[512];
  for (int lineno = 1; fgets(line, sizeof line, f); lineno++) {
    float x, y, z;
    char *s = line + strspn(line, " \t");
    if (*s == '#' || *s == '\n' || *s == '\0') continue;
    if (sscanf(s, "%f %f %f", &x, &y, &z) != 3) {
      fprintf(stderr, "cyclone_secure_peer: --points %s line %d: expected \"x y z\"\n", path,
              lineno);
      exit(2);
    }
    if (len == cap) xyz = realloc(xyz, (cap *= 2) * 3 * sizeof *xyz);
    xyz[3 * len] = x, xyz[3 * len + 1] = y, xyz[3 * len + 2] = z, len++;
  }
  fclose(f);
  *n = (uint32_t)len;
  return xyz;
}

static void stamp_now(sensor_msgs_msg_dds__PointCloud2_ *c) {
  double t = now_s();
  c->header.stamp.sec = (int32_t)t;
  c->header.stamp.nanosec = (uint32_t)((t - (double)(int32_t)t) * 1e9);
}
static void fill_cloud(sensor_msgs_msg_dds__PointCloud2_ *c, const float *xyz, uint32_t n,
                       const char *frame) {
  static sensor_msgs_msg_dds__PointField_ fields[3] = {
      {"x", 0, 7, 1}, {"y", 4, 7, 1}, {"z", 8, 7, 1}};
  memset(c, 0, sizeof *c);
  stamp_now(c);
  c->header.frame_id = (char *)frame;
  c->height = 1;
  c->width = n;
  c->fields._length = c->fields._maximum = 3;
  c->fields._buffer = fields;
  c->is_bigendian = false;
  c->point_step = 16;
  c->row_step = 16 * n;
  c->data._length = c->data._maximum = 16 * n;
  c->data._buffer = calloc(n, 16);
  for (uint32_t i = 0; i < n; i++) memcpy(c->data._buffer + 16 * i, xyz + 3 * i, 12);
  c->is_dense = true;
}

/* A reader of little-endian CDR (XCDR1 as ROS 2 writes it): alignment counted from the end of
 * the 4-byte encapsulation header; every length is checked against the bytes present. */
struct cdr {
  const uint8_t *p;
  size_t len, pos;
  const char *file;
};
static void cdr_need(struct cdr *c, size_t align, size_t n) {
  c->pos = (c->pos + align - 1) / align * align;
  if (c->pos > c->len || n > c->len - c->pos) {
    fprintf(stderr, "cyclone_secure_peer: --cdr %s: truncated at byte %zu (a PointCloud2?)\n",
            c->file, c->pos + 4);
    exit(2);
  }
}
static uint32_t cdr_u32(struct cdr *c) {
  uint32_t v;
  cdr_need(c, 4, 4);
  memcpy(&v, c->p + c->pos, 4);
  c->pos += 4;
  return v;
}
static uint8_t cdr_u8(struct cdr *c) {
  cdr_need(c, 1, 1);
  return c->p[c->pos++];
}
/* A string or byte sequence: its length, then its bytes (a copy, NUL-terminated). */
static char *cdr_bytes(struct cdr *c, uint32_t *n) {
  *n = cdr_u32(c);
  cdr_need(c, 1, *n);
  char *b = malloc((size_t)*n + 1);
  memcpy(b, c->p + c->pos, *n);
  b[*n] = 0;
  c->pos += *n;
  return b;
}
/* The cloud of --cdr FILE, its fields and data as the file has them. */
static void load_cdr(const char *path, sensor_msgs_msg_dds__PointCloud2_ *cloud) {
  FILE *f = fopen(path, "rb");
  if (!f) {
    fprintf(stderr, "cyclone_secure_peer: --cdr %s: %s\n", path, strerror(errno));
    exit(2);
  }
  fseek(f, 0, SEEK_END);
  long size = ftell(f);
  rewind(f);
  uint8_t *bytes = malloc(size > 0 ? (size_t)size : 1);
  if (size < 4 || fread(bytes, 1, (size_t)size, f) != (size_t)size || bytes[1] != 1) {
    fprintf(stderr, "cyclone_secure_peer: --cdr %s: not little-endian CDR (encapsulation %s)\n",
            path, size < 4 ? "missing" : "not CDR_LE");
    exit(2);
  }
  fclose(f);
  struct cdr c = {bytes + 4, (size_t)size - 4, 0, path};
  memset(cloud, 0, sizeof *cloud);
  uint32_t n;
  cdr_u32(&c), cdr_u32(&c); /* the stamp: replaced at each write */
  cloud->header.frame_id = cdr_bytes(&c, &n);
  cloud->height = cdr_u32(&c);
  cloud->width = cdr_u32(&c);
  uint32_t nfields = cdr_u32(&c);
  if (nfields > (c.len - c.pos) / 9) {
    fprintf(stderr, "cyclone_secure_peer: --cdr %s: %u fields in %zu bytes\n", path, nfields,
            c.len - c.pos);
    exit(2);
  }
  cloud->fields._length = cloud->fields._maximum = nfields;
  cloud->fields._buffer = calloc(nfields ? nfields : 1, sizeof *cloud->fields._buffer);
  for (uint32_t i = 0; i < nfields; i++) {
    sensor_msgs_msg_dds__PointField_ *pf = &cloud->fields._buffer[i];
    pf->name = cdr_bytes(&c, &n);
    pf->offset = cdr_u32(&c);
    pf->datatype = cdr_u8(&c);
    pf->count = cdr_u32(&c);
  }
  cloud->is_bigendian = cdr_u8(&c);
  cloud->point_step = cdr_u32(&c);
  cloud->row_step = cdr_u32(&c);
  cloud->data._buffer = (uint8_t *)cdr_bytes(&c, &n);
  cloud->data._length = cloud->data._maximum = n;
  cloud->is_dense = cdr_u8(&c);
  free(bytes);
}
/* The distance of a cloud's nearest point to the origin (the --monitor role). */
static double nearest(const sensor_msgs_msg_dds__PointCloud2_ *c) {
  double best = INFINITY;
  for (uint32_t i = 0; c->point_step >= 12 && i + c->point_step <= c->data._length;
       i += c->point_step) {
    float p[3];
    memcpy(p, c->data._buffer + i, sizeof p);
    double d = sqrt((double)p[0] * p[0] + (double)p[1] * p[1] + (double)p[2] * p[2]);
    if (d < best) best = d;
  }
  return best;
}

static void entity_state(dds_entity_t e, char *out, size_t size) {
  if (e == 0) snprintf(out, size, "none");
  else if (e < 0) snprintf(out, size, "denied: %s", dds_strretcode(e));
  else snprintf(out, size, "ok");
}

static void parse(int argc, char **argv, struct options *o) {
  *o = (struct options){NULL, DEFAULT_PLUGINS, NULL, "rt/camera/depth/points",
                        "rt/ist_monitor/min_distance", NULL, "camera_link", NULL, 0, 0, 0, 0, 0, 30.0, 10.0};
  for (int i = 1; i < argc; i++) {
    const char *a = argv[i], *v = i + 1 < argc ? argv[i + 1] : NULL;
    int *flag = !strcmp(a, "--monitor")    ? &o->monitor
                : !strcmp(a, "--no-cloud") ? &o->no_cloud
                : !strcmp(a, "--no-float") ? &o->no_float
                                           : NULL;
    if (flag) {
      *flag = 1;
      continue;
    }
    if (!v) {
      fprintf(stderr, "cyclone_secure_peer: %s: unknown or without its value\n", a);
      exit(2);
    }
    i++;
    if (!strcmp(a, "--enclave")) o->enclave = v;
    else if (!strcmp(a, "--plugins")) o->plugins = v;
    else if (!strcmp(a, "--trace")) o->trace = v;
    else if (!strcmp(a, "--cloud-topic")) o->cloud_topic = v;
    else if (!strcmp(a, "--float-topic")) o->float_topic = v;
    else if (!strcmp(a, "--points")) o->points = v;
    else if (!strcmp(a, "--frame")) o->frame = v;
    else if (!strcmp(a, "--domain")) o->domain = atoi(v);
    else if (!strcmp(a, "--count")) o->count = atoi(v);
    else if (!strcmp(a, "--timeout")) o->timeout = atof(v);
    else if (!strcmp(a, "--cdr")) o->cdr = v;
    else if (!strcmp(a, "--rate")) o->rate = atof(v);
    else {
      fprintf(stderr, "cyclone_secure_peer: unknown option %s\n", a);
      exit(2);
    }
  }
}

int main(int argc, char **argv) {
  struct options o;
  parse(argc, argv, &o);
  char *xml = config_xml(&o);
  if (xml) {
    dds_entity_t dom = dds_create_domain((dds_domainid_t)o.domain, xml);
    if (dom < 0) die("domain (security or tracing configuration)", dom);
  }
  dds_entity_t pp = dds_create_participant((dds_domainid_t)o.domain, NULL, NULL);
  if (pp < 0) die("participant", pp);
  /* A topic only where it is used: the access control checks the topic itself too. */
  dds_entity_t cloud_t =
      o.no_cloud ? 0
                 : dds_create_topic(pp, &sensor_msgs_msg_dds__PointCloud2__desc, o.cloud_topic,
                                    NULL, NULL);
  dds_entity_t float_t =
      o.no_float
          ? 0
          : dds_create_topic(pp, &std_msgs_msg_dds__Float64__desc, o.float_topic, NULL, NULL);
  dds_qos_t *best_effort = dds_create_qos(), *reliable = dds_create_qos();
  dds_qset_reliability(best_effort, DDS_RELIABILITY_BEST_EFFORT, 0);
  dds_qset_reliability(reliable, DDS_RELIABILITY_RELIABLE, DDS_SECS(1));
  dds_qset_history(reliable, DDS_HISTORY_KEEP_LAST, 100);
  dds_entity_t cloud_e = cloud_t <= 0 ? cloud_t
                         : o.monitor ? dds_create_reader(pp, cloud_t, best_effort, NULL)
                                     : dds_create_writer(pp, cloud_t, best_effort, NULL);
  dds_entity_t float_e = float_t <= 0 ? float_t
                         : o.monitor ? dds_create_writer(pp, float_t, reliable, NULL)
                                     : dds_create_reader(pp, float_t, reliable, NULL);
  char cloud_state[128], float_state[128];
  entity_state(cloud_e, cloud_state, sizeof cloud_state);
  entity_state(float_e, float_state, sizeof float_state);

  uint32_t n = 0;
  float *xyz = o.monitor || o.cdr ? NULL : load_points(o.points, &n);
  sensor_msgs_msg_dds__PointCloud2_ file_cloud;
  if (o.cdr && !o.monitor) load_cdr(o.cdr, &file_cloud);
  if (!(o.rate > 0)) {
    fprintf(stderr, "cyclone_secure_peer: --rate %g: must be above 0\n", o.rate);
    exit(2);
  }
  static double values[MAX_VALUES];
  int nvalues = 0, sent = 0, received = 0;
  double start = now_s(), end = start + o.timeout;
  while (now_s() < end && !(o.count > 0 && nvalues >= o.count)) {
    void *samples[16] = {NULL};
    dds_sample_info_t infos[16];
    if (!o.monitor) {
      if (o.cdr) {
        stamp_now(&file_cloud);
        if (cloud_e > 0 && dds_write(cloud_e, &file_cloud) == DDS_RETCODE_OK) sent++;
      } else {
        sensor_msgs_msg_dds__PointCloud2_ c;
        fill_cloud(&c, xyz, n, o.frame);
        if (cloud_e > 0 && dds_write(cloud_e, &c) == DDS_RETCODE_OK) sent++;
        free(c.data._buffer);
      }
      int k = float_e > 0 ? dds_take(float_e, samples, infos, 16, 16) : 0;
      for (int i = 0; i < k; i++)
        if (infos[i].valid_data && nvalues < MAX_VALUES)
          values[nvalues++] = ((std_msgs_msg_dds__Float64_ *)samples[i])->data;
      if (k > 0) dds_return_loan(float_e, samples, k);
    } else {
      int k = cloud_e > 0 ? dds_take(cloud_e, samples, infos, 16, 16) : 0;
      for (int i = 0; i < k; i++)
        if (infos[i].valid_data) {
          std_msgs_msg_dds__Float64_ d = {nearest(samples[i])};
          received++;
          if (float_e > 0) dds_write(float_e, &d);
          if (nvalues < MAX_VALUES) values[nvalues++] = d.data;
        }
      if (k > 0) dds_return_loan(cloud_e, samples, k);
    }
    if (o.monitor) {
      dds_sleepfor(DDS_MSECS(100));
    } else {
      /* The next write's time on the schedule from the start; none made up for. */
      double next = start + ceil((now_s() - start) * o.rate + 1e-9) / o.rate;
      if (next > now_s()) dds_sleepfor((dds_duration_t)(1e9 * (next - now_s())));
    }
  }
  dds_publication_matched_status_t pm = {0};
  dds_subscription_matched_status_t sm = {0};
  dds_entity_t writer = o.monitor ? float_e : cloud_e, reader = o.monitor ? cloud_e : float_e;
  if (writer > 0) dds_get_publication_matched_status(writer, &pm);
  if (reader > 0) dds_get_subscription_matched_status(reader, &sm);
  uint32_t cloud_matched = o.monitor ? sm.total_count : pm.total_count;
  uint32_t float_matched = o.monitor ? pm.total_count : sm.total_count;
  printf("{\"values\": [");
  for (int i = 0; i < nvalues; i++) printf("%s%.17g", i ? ", " : "", values[i]);
  printf("], \"clouds_sent\": %d, \"clouds_received\": %d, \"cloud_matched\": %u, "
         "\"float_matched\": %u, \"cloud_entity\": \"%s\", \"float_entity\": \"%s\"}\n",
         sent, received, cloud_matched, float_matched, cloud_state, float_state);
  fflush(stdout);
  free(xyz);
  dds_delete(pp);
  return 0;
}
