// Subscribes with LCM's Java library and decodes stride messages with the Java classes that
// lcm-gen -j makes from stride's .lcm files; prints what it decoded, one line per type, and
// exits once it has seen a ping_t, a node_status_t and a joint_trajectory_t.
//
//   java -cp lcm.jar:stride-lcmtypes.jar:. StrideDecode URL
import java.io.IOException;
import lcm.lcm.LCM;
import lcm.lcm.LCMDataInputStream;
import lcm.lcm.LCMSubscriber;

public class StrideDecode implements LCMSubscriber {
    private boolean ping, status, traj;

    public synchronized void messageReceived(LCM lcm, String channel, LCMDataInputStream ins) {
        try {
            if (channel.equals("JAVA_CHECK_PING") && !ping) {
                stride.ping_t p = new stride.ping_t(ins);
                System.out.println("ping_t sequence=" + p.header.sequence + " frame=" + p.header.frame
                        + " payload_size=" + p.payload_size + " last_byte=" + (p.payload[p.payload_size - 1] & 0xff));
                ping = true;
            } else if (channel.equals("JAVA_CHECK_STATUS") && !status) {
                stride.node_status_t s = new stride.node_status_t(ins);
                System.out.println("node_status_t node=" + s.node + " state=" + s.state + " detail=" + s.detail);
                status = true;
            } else if (channel.equals("JAVA_CHECK_TRAJ") && !traj) {
                stride.joint_trajectory_t t = new stride.joint_trajectory_t(ins);
                System.out.println("joint_trajectory_t joints=" + String.join(",", t.joint_names) + " rows="
                        + t.num_rows + " positions[1][2]=" + t.positions[1][2]);
                traj = true;
            }
        } catch (IOException e) {
            System.out.println("decode error on " + channel + ": " + e);
        }
        if (ping && status && traj) {
            System.out.flush();
            System.exit(0);
        }
    }

    public static void main(String[] args) throws IOException {
        LCM lcm = new LCM(args[0]);
        lcm.subscribe("JAVA_CHECK_.*", new StrideDecode());
        System.out.println("subscribed");
        System.out.flush();
        try {
            Thread.sleep(30000);
        } catch (InterruptedException e) {
        }
        System.out.println("timed out");
        System.exit(1);
    }
}
