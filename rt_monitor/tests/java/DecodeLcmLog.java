// java -cp lcm.jar:dynid-lcmtypes.jar:. DecodeLcmLog LOG: every message of the monitor's channels in an LCM log,
// decoded with the generated Java classes, one line each: CHANNEL then field=value pairs (tab-separated; array
// elements comma-separated). test_lcm_deploy.py compares them with the Python decoding of the same log.
import java.io.IOException;
import java.lang.reflect.Array;
import java.lang.reflect.Field;
import java.lang.reflect.Modifier;

import lcm.logging.Log;

public class DecodeLcmLog {
    static String show(Object v) {
        if (v == null || !v.getClass().isArray()) return String.valueOf(v);
        StringBuilder b = new StringBuilder();
        for (int i = 0; i < Array.getLength(v); ++i) {
            if (i > 0) b.append(',');
            b.append(show(Array.get(v, i)));
        }
        return b.toString();
    }

    public static void main(String[] args) throws IOException, IllegalAccessException {
        Log log = new Log(args[0], "r");
        while (true) {
            Log.Event e;
            try {
                e = log.readNext();
            } catch (java.io.EOFException eof) {
                break;
            }
            Object msg;
            switch (e.channel) {
                case "DYNID_CONTACT": msg = new dynid.contact_event_t(e.data); break;
                case "DYNID_STATUS": msg = new dynid.monitor_status_t(e.data); break;
                case "DYNID_RESIDUAL": msg = new dynid.residual_t(e.data); break;
                default: continue;
            }
            StringBuilder line = new StringBuilder(e.channel);
            for (Field f : msg.getClass().getFields()) {
                if (Modifier.isStatic(f.getModifiers())) continue;  // LCM_FINGERPRINT etc.
                line.append('\t').append(f.getName()).append('=').append(show(f.get(msg)));
            }
            System.out.println(line);
        }
        log.close();
    }
}
