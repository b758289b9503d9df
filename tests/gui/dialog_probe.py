"""Run by test_layout in a subprocess (QT_SCALE_FACTOR and the screen are set before Qt
starts): open the main window on the simulated compression rig, then every kind of dialog
it shows (the fault message, the close-loaded and pause-in-hold questions, the file choosers,
about), and write each one's frame, whether it is a message box, has a fixed size or keeps
its text in its details, as JSON, to the file named by the second argument."""

from PySide6.QtWidgets import QMessageBox

from gelrig.gui.mainwindow import CLOSE_LOADED
from tests.gui.layout_probe import connected, done

#: The fault message of the walk of issue 25 (a served force input killed mid-run).
FAULT = ("The link to the force DAQ (USB-6001) was lost: check its power and cable, then "
         "Disconnect and Connect the rig\n\nmotion stopped (verified); plate retracted to "
         "0.000 mm (end of travel: the load could not be read)\n\nThe data recorded so far "
         "is kept.")


def main() -> None:
    app, window = connected()

    def nothing(*_args: object) -> None:
        return None

    dialogs = {
        "fault": lambda: window.message("Fault: the run stopped", FAULT),
        "long fault": lambda: window.message("Fault: the run stopped", "\n\n".join(
            [FAULT] * 12)),
        "about": window.about,
        "close loaded": lambda: (window._ask_close(
            "The sample is loaded", "The sample is loaded (48 mN on the sample).\n\nUnload "
            "it to the rig's safe position and close, close leaving it loaded, or cancel?",
            CLOSE_LOADED, nothing, default="cancel"), window._close_box)[1],
        "pause in hold": lambda: window.protocol.ask_hold(nothing),
        "open protocol": window.choose_protocol,
        "open rig": window.choose_rig,
        "open run": window.choose_run,
        "save protocol as": window.save_protocol_as,
    }
    screen = window.screen().availableGeometry()
    probe = {"screen": [screen.x(), screen.y(), screen.width(), screen.height()]}
    for name, show in dialogs.items():
        shown = show()
        for _ in range(20):
            app.processEvents()
        frame = shown.frameGeometry()
        probe[name] = {"frame": [frame.x(), frame.y(), frame.width(), frame.height()],
                       "message": isinstance(shown, QMessageBox),
                       "fixed": shown.minimumSize() == shown.maximumSize(),
                       "details": isinstance(shown, QMessageBox) and bool(
                           shown.detailedText())}
        shown.close()
        app.processEvents()
    done(window, probe)


if __name__ == "__main__":
    main()
