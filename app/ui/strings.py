"""Every word the app shows, in English and in plain, hiragana-friendly Japanese.

Kept in one table so a translator (or a teacher) can check both languages side by side,
and so a test can prove no key is missing in either language. Japanese uses hiragana
and katakana a first-grader can read; kanji only where a teacher reads it (teacher mode).
"""
from __future__ import annotations

import os

LANGUAGES = ("ja", "en")

STRINGS: dict[str, dict[str, str]] = {
    "app_title": {"en": "StoryBeam", "ja": "ストーリービーム"},
    "my_stories": {"en": "My stories", "ja": "わたしの おはなし"},
    "new_story": {"en": "New story", "ja": "あたらしい おはなし"},
    "choose_arc": {"en": "How long is your story?", "ja": "どんな おはなしに する?"},
    "arc_short": {"en": "Short (3 parts)", "ja": "みじかい (3つ)"},
    "arc_classic": {"en": "Big story (5 parts)", "ja": "ながい (5つ)"},
    "arc_free": {"en": "Free", "ja": "じゆう"},
    "story_n": {"en": "Story {n}", "ja": "おはなし {n}"},
    "scenes_n": {"en": "{n} scenes", "ja": "ばめん {n}"},
    "scene_n": {"en": "Scene {n}", "ja": "ばめん {n}"},
    "part_beginning": {"en": "Beginning", "ja": "はじめ"},
    "part_middle": {"en": "Middle", "ja": "なか"},
    "part_end": {"en": "End", "ja": "おわり"},
    "part_setup": {"en": "Setup", "ja": "はじまり"},
    "part_conflict": {"en": "Problem", "ja": "こまった!"},
    "part_challenge": {"en": "Challenge", "ja": "がんばる"},
    "part_climax": {"en": "Big moment", "ja": "いちばん"},
    "part_resolution": {"en": "Ending", "ja": "おしまい"},
    "background": {"en": "Place", "ja": "ばしょ"},
    "bg_sky": {"en": "Sky", "ja": "そら"},
    "bg_grass": {"en": "Meadow", "ja": "のはら"},
    "bg_night": {"en": "Night", "ja": "よる"},
    "bg_sea": {"en": "Sea", "ja": "うみ"},
    "bg_castle": {"en": "Castle", "ja": "おしろ"},
    "bg_forest": {"en": "Forest", "ja": "もり"},
    "bg_space": {"en": "Space", "ja": "うちゅう"},
    "bg_sand": {"en": "Desert", "ja": "さばく"},
    "characters": {"en": "Who?", "ja": "だれ?"},
    "char_robot": {"en": "Robot", "ja": "ロボット"},
    "char_animal": {"en": "Animal", "ja": "どうぶつ"},
    "char_child": {"en": "Child", "ja": "こども"},
    "motion": {"en": "What do they do?", "ja": "なにを する?"},
    "motion_walk": {"en": "Walk", "ja": "あるく"},
    "motion_run": {"en": "Run", "ja": "はしる"},
    "motion_jump": {"en": "Jump", "ja": "とぶ"},
    "motion_dance": {"en": "Dance", "ja": "おどる"},
    "motion_kick": {"en": "Kick", "ja": "ける"},
    "motion_more": {"en": "More", "ja": "もっと"},
    "more_like_this": {"en": "More like this", "ja": "にている うごき"},
    "no_clips": {"en": "No moves found", "ja": "うごきが ないよ"},
    "pose_button": {"en": "Pose", "ja": "ポーズ"},
    "pose_title": {"en": "Move the figure, find the move", "ja": "にんぎょうを うごかして さがそう"},
    "pose_hint": {"en": "Drag a hand, a foot, the head or the hips", "ja": "て・あし・あたま・こしを ゆびで うごかしてね"},
    "pose_found": {"en": "These moves do that pose", "ja": "この ポーズが ある うごき"},
    "library_loading": {"en": "Getting the moves ready...", "ja": "うごきを じゅんび ちゅう…"},
    "groups_button": {"en": "Groups", "ja": "なかま"},
    "groups_title": {"en": "Moves that go together", "ja": "にている うごきの なかま"},
    "group_n": {"en": "Group {n}", "ja": "なかま {n}"},
    "draw_hint": {"en": "Draw the path with your finger", "ja": "ゆびで みちを かいてね"},
    "pick_character_hint": {"en": "Add someone first", "ja": "まず だれかを えらんでね"},
    "hop": {"en": "Hop", "ja": "ぴょん"},
    "spin": {"en": "Spin", "ja": "くるっ"},
    "undo": {"en": "Undo", "ja": "もどす"},
    "play_again": {"en": "Again", "ja": "もういちど"},
    "save_video": {"en": "Save", "ja": "ほぞん"},
    "video_saved": {"en": "Saved in your Videos, folder StoryBeam.", "ja": "ビデオの StoryBeam フォルダに 保存しました。"},
    "video_saved_android": {"en": "Saved in the gallery (Movies/StoryBeam).", "ja": "ギャラリー (Movies/StoryBeam) に 保存しました。"},
    "video_not_saved": {"en": "The video could not be saved (the app's log says why).",
                        "ja": "動画を保存できませんでした (理由はアプリのログにあります)。"},
    "rename": {"en": "Name", "ja": "なまえ"},
    "say_name": {"en": "Say its name", "ja": "なまえを いう"},
    "story_bin": {"en": "Bin", "ja": "ごみばこ"},
    "restore": {"en": "Bring back", "ja": "もどす"},
    "empty_bin": {"en": "Empty the bin", "ja": "ごみばこを 空にする"},
    "bin_emptied": {"en": "{n} stories deleted for good", "ja": "{n}この おはなしを 消しました"},
    "video_saving_setting": {"en": "Children save videos", "ja": "こどもが 動画を保存"},
    "redo": {"en": "Redo", "ja": "やりなおす"},
    "play": {"en": "Play", "ja": "みる"},
    "pause": {"en": "Pause", "ja": "とめる"},
    "play_scene": {"en": "This scene", "ja": "この ばめん"},
    "play_story": {"en": "Whole story", "ja": "ぜんぶ"},
    "home": {"en": "Home", "ja": "ホーム"},
    "back": {"en": "Back", "ja": "もどる"},
    "add_scene": {"en": "Add", "ja": "ふやす"},
    "duplicate": {"en": "Copy", "ja": "コピー"},
    "delete": {"en": "Delete", "ja": "けす"},
    "edit": {"en": "Edit", "ja": "なおす"},
    "projector": {"en": "Projector", "ja": "うつす"},
    "preview": {"en": "Preview", "ja": "ためしに みる"},
    "language": {"en": "日本語", "ja": "English"},
    "teacher": {"en": "Teacher", "ja": "せんせい"},
    "enter_pin": {"en": "Teacher PIN", "ja": "せんせいの ばんごう"},
    "new_pin": {"en": "Choose a PIN (4-8 digits)", "ja": "あたらしい ばんごう (4-8けた)"},
    "wrong_pin": {"en": "Wrong PIN", "ja": "ばんごうが ちがうよ"},
    "gate_title": {"en": "For grown-ups: type this number in digits", "ja": "おとなの かたへ: この数を 数字で入力してください"},
    "gate_wait": {"en": "Locked. Try again in {time}", "ja": "ロック中です。{time} 後に もう一度"},
    "gate_wrong": {"en": "Not quite. Please ask a grown-up.", "ja": "ちがいます。おとなの ひとに きいてね。"},
    "repeat_pin": {"en": "Type the same PIN again", "ja": "同じ番号を もう一度"},
    "pin_mismatch": {"en": "The two PINs were different. Choose again.", "ja": "ちがう番号でした。もう一度 えらんでください。"},
    "pin_digits": {"en": "A PIN has 4 to 8 digits", "ja": "番号は 4-8けたです"},
    "pin_wait": {"en": "Too many wrong tries. Try again in {time}", "ja": "まちがいが おおいので {time} まってね"},
    "forgot_pin": {"en": "Forgot PIN?", "ja": "番号を忘れた"},
    "enter_recovery": {"en": "Type the 12-digit recovery code", "ja": "12けたの リカバリーコードを入力"},
    "wrong_code": {"en": "Wrong recovery code", "ja": "リカバリーコードが ちがいます"},
    "recovery_title": {"en": "Your recovery code", "ja": "リカバリーコード"},
    "recovery_note": {"en": "Write this code down and keep it safe: it resets a forgotten PIN (your stories are kept). "
                            "It is shown only this once.",
                      "ja": "このコードを 書きとめて 大切に しまってください。番号を忘れたときに 使います (おはなしは 消えません)。"
                            "表示は 一度だけです。"},
    "recovery_done": {"en": "I wrote it down", "ja": "書きとめました"},
    "ok": {"en": "OK", "ja": "OK"},
    "clear": {"en": "Clear", "ja": "けす"},
    "sessions": {"en": "Class sessions", "ja": "じゅぎょう"},
    "new_session": {"en": "New session", "ja": "新しい授業"},
    "roster": {"en": "Groups", "ja": "グループ"},
    "add_group": {"en": "Add group", "ja": "グループを追加"},
    "group_name": {"en": "Group name", "ja": "グループ名"},
    "members": {"en": "Nicknames, comma separated", "ja": "ニックネーム (カンマ区切り)"},
    "calibration": {"en": "Calibrate", "ja": "キャリブレーション"},
    "present_all": {"en": "Present all", "ja": "ぜんぶ 見せる"},
    "export_video": {"en": "Export videos", "ja": "動画を書き出す"},
    "export_packages": {"en": "Export packages", "ja": "パッケージを書き出す"},
    "import_package": {"en": "Import package", "ja": "パッケージを読み込む"},
    "export_log": {"en": "Export activity CSV", "ja": "活動ログCSV"},
    "activity_log": {"en": "Activity log", "ja": "活動ログ"},
    "on": {"en": "On", "ja": "オン"},
    "off": {"en": "Off", "ja": "オフ"},
    "exported_to": {"en": "Saved to {path}", "ja": "{path} に保存しました"},
    "not_available": {"en": "Not available on this device: {why}", "ja": "この端末では使えません: {why}"},
    "calib_intro": {"en": "Calibration: follow the steps", "ja": "キャリブレーション: じゅんばんに すすめてね"},
    "calib_next": {"en": "Next step", "ja": "つぎへ"},
    "calib_done": {"en": "Calibration finished", "ja": "キャリブレーション かんりょう"},
    "damaged_backup_pin": {"en": "For the teacher: the class's file is damaged (it is kept as it is). "
                                 "The copy saved {date}, with {n} stories and the teacher PIN, can be put back.",
                           "ja": "先生へ: クラスの ファイルが こわれています(そのまま 保管します)。"
                                 "{date} に保存した コピー(おはなし {n}こ・先生の番号つき)に もどせます。"},
    "damaged_backup": {"en": "For the teacher: the class's file is damaged (it is kept as it is). "
                             "The copy saved {date}, with {n} stories, can be put back.",
                       "ja": "先生へ: クラスの ファイルが こわれています(そのまま 保管します)。"
                             "{date} に保存した コピー(おはなし {n}こ)に もどせます。"},
    "damaged_none": {"en": "For the teacher: the class's file {name} is damaged and kept as it is; there is no "
                           "saved copy, so the children go on in a new file.",
                     "ja": "先生へ: クラスの ファイル {name} が こわれています(そのまま 保管します)。"
                           "コピーが ないので、あたらしい ファイルで つづけます。"},
    "restore_copy": {"en": "Put back the copy", "ja": "コピーに もどす"},
    "continue_new": {"en": "Continue", "ja": "つづける"},
    "restored": {"en": "The copy is back. The damaged file is kept as {name}.",
                 "ja": "コピーに もどしました。こわれた ファイルは {name} として 保管しました。"},
    "restore_failed": {"en": "The copy could not be put back; the damaged file is kept as it is.",
                       "ja": "コピーに もどせませんでした。こわれた ファイルは そのまま です。"},
    "error": {"en": "Oops: {why}", "ja": "あれれ: {why}"},
    "track_tracking": {"en": "tracking", "ja": "みえてる"},
    "track_holding": {"en": "holding", "ja": "ちょっと まって"},
    "track_lost": {"en": "board lost", "ja": "ボードが みえない"},
    "rig_live": {"en": "rig", "ja": "リグ"},
    "rig_preview": {"en": "preview rig", "ja": "れんしゅう リグ"},
    "projector_mode": {"en": "Full screen", "ja": "ぜんがめん"},
    "rig_camera": {"en": "Rig camera", "ja": "リグの カメラ"},
    "rig_camera_hint": {"en": "0, 1 ... = camera; a video file or a folder of images = recording",
                        "ja": "0, 1 ... = カメラ / どうが や がぞうの フォルダ = ろくが"},
    "rig_camera_saved": {"en": "Rig camera: {source} (used when the projector screen next opens)",
                         "ja": "リグの カメラ: {source} (つぎに うつす ときから)"},
    "flat_2d": {"en": "2-D (no 3-D renderer)", "ja": "2D (3Dが つかえない)"},
    "import_pick": {"en": "Tap a story package to import it", "ja": "読み込むパッケージをタップ"},
    "import_none": {"en": "No story packages (.zip) found in:\n{where}", "ja": "パッケージ (.zip) がありません:\n{where}"},
    "imported": {"en": "Imported \"{title}\"", "ja": "「{title}」を読み込みました"},
    "export_progress": {"en": "Video {i}/{n}: {done}/{total} frames", "ja": "動画 {i}/{n}: {done}/{total} フレーム"},
    "video_2d_note": {"en": "2-D video: {why}", "ja": "2D動画: {why}"},
    # voice narration (issue 14)
    "narration": {"en": "Voice", "ja": "こえ"},
    "narration_title": {"en": "Your voice for this scene", "ja": "この ばめんの こえ"},
    "narration_none": {"en": "No voice yet", "ja": "まだ こえが ないよ"},
    "narration_length": {"en": "Voice: {s} s", "ja": "こえ: {s} びょう"},
    "narration_new": {"en": "New voice: {s} s. Trim it, then keep it", "ja": "あたらしい こえ: {s} びょう。きって、「これに する」"},
    "record": {"en": "Record", "ja": "ろくおん"},
    "stop_recording": {"en": "Stop", "ja": "とめる"},
    "recording_now": {"en": "Recording... {s} s", "ja": "ろくおん ちゅう… {s} びょう"},
    "listen": {"en": "Listen", "ja": "きく"},
    "import_audio": {"en": "Sound file", "ja": "おとの ファイル"},
    "trim": {"en": "Trim", "ja": "きる"},
    "trim_start": {"en": "Start: {s} s", "ja": "はじめ: {s} びょう"},
    "trim_end": {"en": "End: {s} s", "ja": "おわり: {s} びょう"},
    "keep_voice": {"en": "Keep", "ja": "これに する"},
    "remove_voice": {"en": "Remove", "ja": "けす"},
    "recording_off": {"en": "Recording is switched off by your teacher", "ja": "せんせいが ろくおんを とめて いるよ"},
    "recording_unavailable": {"en": "No recording here: {why}", "ja": "ここでは ろくおん できないよ: {why}"},
    "recording_limit": {"en": "That is the longest a voice can be", "ja": "こえは これより ながく できないよ"},
    "audio_pick": {"en": "Tap a sound file (WAV or OGG)", "ja": "おとの ファイルを タップしてね (WAV か OGG)"},
    "audio_none": {"en": "No WAV or OGG files found in:\n{where}", "ja": "WAV や OGG の ファイルが ないよ:\n{where}"},
    "recording_setting": {"en": "Voice recording", "ja": "音声の録音"},
    # "Act it out" (issue 18): the child's words in hiragana; the teacher's switch may use kanji
    "act_it_out": {"en": "Act it out", "ja": "やってみせて"},
    "act_title": {"en": "Show me the move!", "ja": "うごきを みせてね!"},
    "act_hint": {"en": "Stand in the outline, then tap Start", "ja": "わくの なかに たって、スタートを タップしてね"},
    "act_start": {"en": "Start", "ja": "スタート"},
    "act_again": {"en": "Again", "ja": "もう いちど"},
    "act_get_ready": {"en": "Get ready...", "ja": "よーい…"},
    "act_go": {"en": "Go!", "ja": "どん!"},
    "act_moving": {"en": "Move now!", "ja": "うごいて!"},
    "act_looking": {"en": "Looking for moves like yours...", "ja": "にている うごきを さがして いるよ…"},
    "act_found": {"en": "Moves like yours: tap one", "ja": "にている うごき: ひとつ タップしてね"},
    "act_step_back": {"en": "Step back: I need to see all of you", "ja": "うしろに さがってね。からだ ぜんぶを みせてね"},
    "act_lift_head": {"en": "Lift your head: I need to see your face", "ja": "かおを あげてね。かおを みせてね"},
    "act_no_body": {"en": "I can't see you: stand in the outline", "ja": "みえないよ。わくの なかに たってね"},
    "act_unavailable": {"en": "The camera can't be used now: {why}", "ja": "いまは カメラが つかえないよ: {why}"},
    "act_setting": {"en": "Act it out (camera)", "ja": "「やってみせて」(カメラ)"},
    # notices (app.ui.notices): a picture first; this one sentence is for the grown-ups and
    # is spoken where the device can speak
    "notice_add_someone": {"en": "Add a character first.", "ja": "さきに だれかを えらんでね。"},
    "notice_sound_broken": {"en": "This sound cannot be played. Try another one.",
                            "ja": "この おとは ならせないよ。ほかの おとに してね。"},
    "notice_sound_long": {"en": "This sound is too long: cut it shorter.",
                          "ja": "この おとは ながすぎるよ。みじかく きってね。"},
    "notice_sound_silent": {"en": "Nothing was heard. Speak closer and try again.",
                            "ja": "なにも きこえなかったよ。ちかくで もう いちど はなしてね。"},
    "notice_no_microphone": {"en": "No microphone here: ask a grown-up.",
                             "ja": "マイクが ないよ。おとなの ひとに きいてね。"},
    "notice_recording_off": {"en": "Recording is switched off by the teacher.",
                             "ja": "せんせいが ろくおんを とめて いるよ。"},
    "notice_file_broken": {"en": "This file cannot be opened.", "ja": "この ファイルは ひらけないよ。"},
    "notice_file_big": {"en": "This file is too big: ask a grown-up to cut it.",
                        "ja": "この ファイルは おおきすぎるよ。おとなの ひとに きいてね。"},
    "notice_story_full": {"en": "This story has no room for more voice.",
                          "ja": "この おはなしには もう こえが はいらないよ。"},
    "notice_no_camera": {"en": "The camera cannot be used now.", "ja": "いまは カメラが つかえないよ。"},
    "notice_storage": {"en": "The stories could not be saved or opened: ask a grown-up.",
                       "ja": "おはなしを ほぞん できなかったよ。おとなの ひとに きいてね。"},
    "notice_grown_up": {"en": "This is for grown-ups.", "ja": "ここは おとなの ひと ようだよ。"},
    "notice_wait": {"en": "Please wait a little.", "ja": "すこし まってね。"},
    "notice_oops": {"en": "That did not work. Try again.", "ja": "うまく いかなかったよ。もう いちど やってみてね。"},
    "audio_none_here": {"en": "No sounds yet: a grown-up can put WAV or OGG files in the StoryBeam folder.",
                        "ja": "おとが まだ ないよ。おとなの ひとに いれて もらってね。"},
}


def device_language(platform: str, environ: dict[str, str] | None = None) -> str:
    """The app language for the device's own (its first launch): Japanese for a Japanese
    device, English for every other (the teacher can switch). Android: the system
    ``Locale``; a desktop: ``LANGUAGE``, ``LC_ALL``, ``LC_MESSAGES``, ``LANG``, as gettext
    reads them."""
    code = ""
    if platform == "android":  # pragma: no cover - needs an Android device
        try:
            from jnius import autoclass  # optional: pyjnius (Android only)
            code = str(autoclass("java.util.Locale").getDefault().getLanguage())
        except Exception:  # noqa: BLE001 - no locale: English
            code = ""
    else:
        env = os.environ if environ is None else environ
        for name in ("LANGUAGE", "LC_ALL", "LC_MESSAGES", "LANG"):
            if env.get(name):
                code = env[name].split(":")[0]
                break
    return "ja" if code.lower().startswith("ja") else "en"


def tr(key: str, lang: str, **values: object) -> str:
    """The text for ``key`` in ``lang`` (falls back to English, then to the key itself)."""
    entry = STRINGS.get(key)
    if entry is None:
        return key
    text = entry.get(lang) or entry.get("en") or key
    return text.format(**values) if values else text
